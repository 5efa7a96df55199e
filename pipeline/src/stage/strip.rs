//! Stage *strip*: adjacency, Strip-RT, strip encoding, the chunk's own top-level hierarchy and
//! its strip-record layout (`reducem::conversion`), chunks in parallel on the rayon pool. Each chunk is
//! a unit of its own in the manifest, so a killed run keeps every chunk it finished. Memory is
//! about threads × one chunk ([`for_each_unit`]).

use anyhow::Context;
use reducem::conversion::{encode_chunk_on, ChunkLayout, Pooling};
use reducem::strip_encoding::EncodedStrip;
use reducem::toplevel::TopLevelParams;

use crate::checksum::Checksum;
use crate::chunk_io::{self, StripChunkHeader};
use crate::fingerprint::Fingerprint;
use crate::lock::ChunkLock;
use crate::manifest::Freshness;
use crate::stage::chunk::Chunked;
use crate::stage::{for_each_unit, Job, Shard, StageName, UpstreamPending};
use crate::workdir::{mesh_chunk, strip_chunk};

/// The manifest key of one chunk's unit.
pub fn unit(chunk: usize) -> String {
    format!("strip/chunk-{chunk:06}")
}

pub fn fingerprint(job: &Job, chunked: &Chunked, chunk: usize) -> Fingerprint {
    let strip = &job.config.strip;
    Fingerprint::new()
        .with("chunk_stage", &chunked.digest)
        .with("chunk", chunk)
        .with("strip.max_length", strip.max_length)
        // Named before `[strip] leaf_windows` was; kept so existing work directories stay fresh.
        .with(
            "strip.leaf_triangles",
            job.config.build_params().leaf_windows,
        )
        .with("strip.sah_bins", strip.sah_bins)
        .with("vertices.grid_bits", grid_bits(job))
        .with("top_level", format!("{:?}", TopLevelParams::default()))
        .with(
            "strip.chunk_magic",
            String::from_utf8_lossy(&chunk_io::STRIP_MAGIC),
        )
}

/// `[vertices] grid_bits` when the encoding uses it, else "none" (f32 vertices).
fn grid_bits(job: &Job) -> String {
    job.config
        .build_params()
        .grid_bits
        .map_or("none".to_string(), |bits| bits.to_string())
}

/// Digest over every chunk's fingerprint: what later stages depend on.
pub fn digest(job: &Job, chunked: &Chunked) -> String {
    let mut all = Fingerprint::new();
    for chunk in 0..chunked.chunk_count() {
        all.add(&unit(chunk), fingerprint(job, chunked, chunk).digest());
    }
    all.digest()
}

/// Chunks of `shard` whose unit is not fresh.
pub fn pending_chunks(job: &Job, chunked: &Chunked, shard: Shard) -> Vec<usize> {
    (0..chunked.chunk_count())
        .filter(|&chunk| shard.owns(chunk))
        .filter(|&chunk| {
            job.freshness(&unit(chunk), &fingerprint(job, chunked, chunk)) != Freshness::Fresh
        })
        .collect()
}

pub fn run(job: &Job, chunked: &Chunked, shard: Shard) -> anyhow::Result<String> {
    let pending = pending_chunks(job, chunked, shard);
    let owned = (0..chunked.chunk_count())
        .filter(|&c| shard.owns(c))
        .count();
    let progress = job.progress.stage("strip", owned as u64, "chunks");
    progress.advance((owned - pending.len()) as u64);
    let converted = std::sync::atomic::AtomicUsize::new(0);
    for_each_unit(&pending, |chunk| {
        let lock_path = job.work.file(&format!("locks/chunk-{chunk:06}.lock"));
        let Some(_lock) = ChunkLock::try_acquire(&lock_path)? else {
            return Ok(());
        };
        job.reload_manifest();
        let fingerprint = fingerprint(job, chunked, chunk);
        let freshness = job.freshness(&unit(chunk), &fingerprint);
        if freshness != Freshness::Fresh {
            job.note_rebuild("strip", &freshness, &format!("chunk {chunk}"));
            let written = strip_one(job, chunked, chunk).context(crate::error::InChunk(chunk))?;
            job.complete(&unit(chunk), &fingerprint, &[written])?;
            converted.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        progress.advance(1);
        Ok(())
    })?;
    job.reload_manifest();
    let still_pending = pending_chunks(job, chunked, shard);
    if let Some(&first) = still_pending.first() {
        return Err(UpstreamPending {
            needed: StageName::Strip,
            reason: format!(
                "{} chunks of this shard are held by another task, first {first}",
                still_pending.len()
            ),
        }
        .into());
    }
    let converted = converted.into_inner();
    progress.finish(&format!(
        ", {converted} chunks converted, {} fresh or taken by other tasks",
        owned - converted
    ));
    Ok(digest(job, chunked))
}

/// Converts one mesh chunk to its strip chunk; the strip chunk's name and checksum.
fn strip_one(job: &Job, chunked: &Chunked, chunk: usize) -> anyhow::Result<(String, Checksum)> {
    let mesh_path = job.work.file(&mesh_chunk(chunk));
    let mesh = chunk_io::read_mesh(&mesh_path)
        .with_context(|| format!("reading {}", mesh_path.display()))?;
    let params = job.config.build_params();
    // One grid over the whole model, the same for every chunk.
    let grid = params.grid(&chunked.bounds());
    let mut encoded = encode_chunk_on(&mesh, &params, grid.as_ref());
    drop(mesh);
    let layout = match Pooling::of(&params, grid.as_ref()) {
        Some(pooling) => ChunkLayout::pooled(&mut encoded.strips, &params.top_level, pooling)?,
        None => ChunkLayout::new(&encoded.strips, &params.top_level)?,
    };
    if let Some(stored) = layout.pooled_vertices {
        encoded.stats.stored_vertices = stored;
    }
    let strips: Vec<&EncodedStrip> = layout.strips(&encoded.strips).collect();
    let header = StripChunkHeader::new(
        &encoded.stats,
        &layout.bounds,
        layout.top.nodes.len(),
        &strips,
    );
    job.write_output(&strip_chunk(chunk), |mut out| {
        chunk_io::write_strips(
            &mut out,
            &header,
            &layout.top.nodes,
            &layout.records,
            &strips,
        )
    })
}
