//! `pipeline run`: for now the one-chunk, in-memory conversion (read, Strip-RT, encode, top
//! level, write). The staged, resumable, out-of-core runner replaces the body of [`run`].

use std::path::Path;
use std::time::Instant;

use anyhow::Context;

use crate::config::{Config, Input};
use reducem::gen;

pub fn run(config_path: &Path) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = Config::load(config_path)?;
    let work_dir = config.work_dir();
    std::fs::create_dir_all(&work_dir)
        .with_context(|| format!("creating {}", work_dir.display()))?;
    let input_path = match config.input().map_err(anyhow::Error::msg)? {
        Input::File(path) => path,
        Input::Generate {
            kind,
            triangles,
            seed,
        } => {
            let path =
                work_dir.join(format!("generated-{kind:?}-{triangles}-{seed}.ply").to_lowercase());
            if !path.exists() {
                log(&format!(
                    "generating {kind:?} mesh, {triangles} triangles, seed {seed}"
                ));
                gen::generate(kind, triangles, seed, &path)?;
            }
            path
        }
    };
    log(&format!("reading {}", input_path.display()));
    let mesh = reducem::input::read_mesh(&input_path)?;
    log(&format!(
        "{} triangles, {} vertices; converting",
        mesh.triangles.len(),
        mesh.positions.len()
    ));
    if let Some(parent) = config
        .output
        .path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
    {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let stats = reducem::build::convert_mesh(&mesh, &config.build_params(), &config.output.path)?;
    let bytes = std::fs::metadata(&config.output.path)?.len();
    log(&format!(
        "wrote {}: {} triangles in {} bytes ({:.2} bytes/triangle), {} dropped, {:.1} s",
        config.output.path.display(),
        stats.triangles,
        bytes,
        bytes as f64 / stats.triangles.max(1) as f64,
        stats.dropped_triangles,
        started.elapsed().as_secs_f64()
    ));
    Ok(())
}

fn log(message: &str) {
    eprintln!("pipeline: {message}");
}
