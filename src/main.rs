//! The `reducem` command: inspect, decode, query and render ReduceM files.

mod closest;
mod crossings;
mod inside;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::{Parser, Subcommand};
use reducem::atomic;
use reducem::exit_code::{self, UsageError};
use reducem::format::reader::{FormatError, ReducemFile, Validation};
use reducem::geometry::Point;
use reducem::output::Destination;
use reducem::render::image::{ImageError, ImageFormat};
use reducem::render::scene::Scene;
use reducem::trace::ray_file::{self, Answer, HitFormat, InvalidRays, RayFile, RayFileError};
use reducem::trace::{Kernel, TraceOptions, Tracer};

#[derive(Parser)]
#[command(
    name = "reducem",
    version,
    about = "Inspect, decode, query and render ReduceM files",
    after_help = exit_code::HELP
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the statistics of a ReduceM file.
    #[command(after_help = exit_code::HELP)]
    Inspect {
        /// The ReduceM file.
        file: PathBuf,
        /// One JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Also verify every section checksum (reads the whole file).
        #[arg(long)]
        verify: bool,
    },
    /// Write every encoded triangle, in input winding, as binary little-endian PLY (positions as
    /// stored: the quantized ones for a grid file).
    #[command(after_help = exit_code::HELP)]
    Decode {
        /// The ReduceM file.
        file: PathBuf,
        /// The PLY file to write (replaced atomically; never the input itself); `-` for standard
        /// output, and a device or FIFO is written directly.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Trace a binary ray file (f32 x 8 per ray: origin, direction, tmin, tmax) and write the
    /// closest hits (f32 x 4 per ray: t, normal; t = inf on a miss; --format full for 48 bytes
    /// with face id, shading normal and colour) or, with --occluded, one byte per ray
    /// (1 = occluded). Prints a summary line on stderr.
    #[command(after_help = exit_code::HELP)]
    Query {
        /// The ReduceM file.
        file: PathBuf,
        /// The ray file to trace; `-` for standard input, and a pipe, FIFO or device is read to
        /// its end.
        #[arg(long)]
        rays: PathBuf,
        /// The hit or occlusion file to write (replaced atomically; never an input); `-` for
        /// standard output, and a device or FIFO is written directly, in ray order.
        #[arg(short, long)]
        output: PathBuf,
        /// Answer occlusion (any hit within [tmin, tmax]) instead of the closest hit.
        #[arg(long)]
        occluded: bool,
        /// What an invalid ray (NaN, zero direction, tmin > tmax) does: reject the whole file,
        /// or be answered as a miss (counted in the summary).
        #[arg(long, value_enum, default_value_t = InvalidRayAnswer::Reject)]
        invalid_rays: InvalidRayAnswer,
        /// The hit record: compact (16 bytes: f32 t, f32 x 3 geometric normal) or full (48
        /// bytes, little endian: f32 t, u, v; u32 face id, 0xFFFFFFFF on a miss or without face
        /// ids; f32 x 3 geometric normal; f32 x 3 shading normal, the interpolated stored normal
        /// else the geometric one; u8 x 4 RGBA colour interpolated, zeros without colours; u32
        /// zero).
        #[arg(long, value_enum, default_value_t = HitRecord::Compact, conflicts_with = "occluded")]
        format: HitRecord,
        /// Count every crossing in [tmin, tmax] instead: a u32 per ray. A crossing through an
        /// edge or a vertex counts once (docs/QUERIES.md).
        #[arg(long, conflicts_with_all = ["occluded", "format", "all"])]
        count: bool,
        /// List every crossing in [tmin, tmax] instead: per ray a u32 n, then n records of 16
        /// bytes (f32 t, u32 face id, f32 u, f32 v), t ascending, ties by face id.
        #[arg(long, conflicts_with_all = ["occluded", "format"])]
        all: bool,
    },
    /// Find the closest surface point to each point of a binary point file (f32 x 3 per point)
    /// and write 32 bytes per point: distance, point, face id, barycentrics, flags. Prints a
    /// summary line on stderr.
    #[command(after_help = exit_code::HELP)]
    Closest(closest::ClosestArgs),
    /// Tell for each point of a binary point file (f32 x 3 per point) whether it is inside the
    /// surface: one byte per point, 1 inside. Exact on a closed mesh (one ray's parity), else
    /// the majority of --samples rays. Prints a summary line on stderr.
    #[command(after_help = exit_code::HELP)]
    Inside(inside::InsideArgs),
    /// Render an image of the model as a scene file describes it, tracing only the effects the
    /// scene asks for. Every scene key, its default and unit: docs/SCENES.md.
    #[command(after_help = exit_code::HELP, allow_negative_numbers = true)]
    Render {
        /// The ReduceM file.
        file: PathBuf,
        /// The scene file (TOML; see docs/SCENES.md and configs/scenes/); `-` for standard input.
        #[arg(long)]
        scene: PathBuf,
        /// The image to write, its format by extension: .png (8-bit sRGB) or .pfm (linear
        /// floats); replaced atomically, never an input. `-` writes a PNG to standard output
        /// (the report then goes to standard error); a device or FIFO is written directly.
        #[arg(short, long)]
        output: PathBuf,
        /// Print the report as one JSON object.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        overrides: SceneOverrides,
    },
    /// Serve an interactive view of a ReduceM file to a browser (runs the reducem-view binary:
    /// `reducem view FILE [--bind ADDR:PORT] [--scene SCENE.toml] [--up y|z] [--threads N]`).
    #[command(disable_help_flag = true)]
    View {
        /// The arguments of reducem-view.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<std::ffi::OsString>,
    },
}

impl Command {
    /// The ReduceM file the command reads.
    fn model(&self) -> Option<&Path> {
        match self {
            Command::Inspect { file, .. }
            | Command::Decode { file, .. }
            | Command::Query { file, .. }
            | Command::Render { file, .. } => Some(file),
            Command::Closest(args) => Some(&args.file),
            Command::Inside(args) => Some(&args.file),
            Command::View { .. } => None,
        }
    }
}

/// Command-line replacements for scene keys (docs/SCENES.md), applied after `--up`.
#[derive(Clone, Debug, clap::Args)]
struct SceneOverrides {
    /// The model's up axis: scenes are written for z-up models; y turns every position and
    /// direction of the scene for a y-up model (such as the Stanford bunny). Default: the axis
    /// stored in the file (`[input] up` at conversion), else z.
    #[arg(long, value_enum)]
    up: Option<UpAxis>,
    /// Image width in pixels ([image] width).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels ([image] height).
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel along each axis: N traces N x N per pixel ([image] antialiasing).
    #[arg(long)]
    antialiasing: Option<u32>,
    /// Camera position X,Y,Z in model units ([camera] position); needs --look-at.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true,
          requires = "look_at")]
    camera_position: Option<Point>,
    /// The point X,Y,Z seen at the image centre ([camera] look_at); needs --camera-position.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true,
          requires = "camera_position")]
    look_at: Option<Point>,
    /// The direction X,Y,Z that is up in the image ([camera] up).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true)]
    camera_up: Option<Point>,
    /// Vertical field of view in degrees ([camera] fov_degrees).
    #[arg(long)]
    fov: Option<f32>,
    /// Ambient-occlusion rays per pixel ([ambient_occlusion] samples); 0 turns AO off.
    #[arg(long)]
    ao_samples: Option<u32>,
    /// Ambient-occlusion distance in model units ([ambient_occlusion] max_distance).
    #[arg(long)]
    ao_distance: Option<f32>,
    /// Multiplier of the linear radiance before encoding ([shading] exposure).
    #[arg(long)]
    exposure: Option<f32>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum UpAxis {
    /// The model's up axis is y: the scene is turned.
    Y,
    /// The model's up axis is z, as scenes are written.
    Z,
}

/// `X,Y,Z` as a point.
fn parse_point(text: &str) -> Result<Point, String> {
    let values: Vec<f32> = text
        .split(',')
        .map(|value| value.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|error| format!("{text:?}: {error}"))?;
    <[f32; 3]>::try_from(values).map_err(|_| format!("{text:?} is not three numbers X,Y,Z"))
}

/// `reducem query --format`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum HitRecord {
    /// 16 bytes per ray: t and the geometric normal.
    Compact,
    /// 48 bytes per ray: t, barycentrics, face id, both normals and colour.
    Full,
}

impl HitRecord {
    fn format(self) -> HitFormat {
        match self {
            HitRecord::Compact => HitFormat::Compact,
            HitRecord::Full => HitFormat::Full,
        }
    }
}

/// `reducem query --invalid-rays`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum InvalidRayAnswer {
    /// One invalid ray rejects the whole ray file (exit code 65), before anything is traced.
    Reject,
    /// Each invalid ray is answered as a miss (not occluded); the summary counts them.
    Miss,
}

impl From<InvalidRayAnswer> for InvalidRays {
    fn from(answer: InvalidRayAnswer) -> InvalidRays {
        match answer {
            InvalidRayAnswer::Reject => InvalidRays::Reject,
            InvalidRayAnswer::Miss => InvalidRays::Miss,
        }
    }
}

fn main() -> ExitCode {
    // Signals remove this process's temporaries; a truncated mapped file ends it with 74.
    let _ = reducem_core::signals::install_for_tool();
    let cli = match reducem::cli::parse_or_exit::<Cli>() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("reducem: error: {error:#}");
            ExitCode::from(exit_code_of(&error))
        }
    }
}

/// The exit code of an error (the table in `exit_code`), by the typed errors in its chain.
fn exit_code_of(error: &anyhow::Error) -> u8 {
    exit_code::classify(error, reducem_exit).0
}

/// The exit of the error types only `reducem` meets.
fn reducem_exit(cause: &(dyn std::error::Error + 'static)) -> Option<exit_code::Exit> {
    if cause.is::<reducem::trace::kernel::KernelError>() {
        return Some((exit_code::USAGE, "usage"));
    }
    if cause.is::<reducem::render::scene::SceneError>() {
        return Some((exit_code::CONFIG, "config"));
    }
    if let Some(error) = cause.downcast_ref::<FormatError>() {
        return io_or_bad_input(matches!(error, FormatError::Io { .. }));
    }
    if let Some(error) = cause.downcast_ref::<RayFileError>() {
        return io_or_bad_input(matches!(error, RayFileError::Io { .. }));
    }
    if let Some(error) = cause.downcast_ref::<closest::PointFileError>() {
        return io_or_bad_input(matches!(error, closest::PointFileError::Io { .. }));
    }
    if cause.is::<reducem::render::image::ImageError>() {
        return Some((exit_code::IO, "io"));
    }
    None
}

/// 74 for a file that could not be read, 65 for one that was read and is malformed.
fn io_or_bad_input(is_io: bool) -> Option<exit_code::Exit> {
    Some(match is_io {
        true => (exit_code::IO, "io"),
        false => (exit_code::BAD_INPUT, "bad_input"),
    })
}

fn run(cli: Cli) -> anyhow::Result<()> {
    if let Some(model) = cli.command.model() {
        reducem::cli::check_mappable(model)?;
    }
    match cli.command {
        Command::Inspect { file, json, verify } => inspect(&file, json, verify),
        Command::Decode { file, output } => {
            let output = Destination::prepare(&output, &[&file])?;
            let opened = ReducemFile::open_with(&file, Validation::Full)?;
            output
                .write(|out| reducem::decode::write_ply_to(&opened, out))
                .with_context(|| format!("writing {}", output.name()))
        }
        Command::Query {
            file,
            rays,
            output,
            occluded,
            invalid_rays,
            format,
            count,
            all,
        } => {
            let output = Destination::prepare(&output, &[&file, &rays])?;
            let every = match (count, all) {
                (true, _) => Some(crossings::Crossings::Count),
                (_, true) => Some(crossings::Crossings::All),
                _ => None,
            };
            if let Some(mode) = every {
                return crossings::run(&file, &rays, &output, mode, invalid_rays.into());
            }
            let answer = match occluded {
                true => Answer::Occlusion,
                false => Answer::Hits(format.format()),
            };
            query(&file, &rays, &output, answer, invalid_rays.into())
        }
        Command::Closest(args) => closest::run(args),
        Command::Inside(args) => inside::run(args),
        Command::View { args } => exec_viewer(args),
        Command::Render {
            file,
            scene,
            output,
            json,
            overrides,
        } => {
            let destination = Destination::prepare(&output, &[&file, &scene])?;
            let format = image_format(&output)?;
            let scene = Scene::load(&scene)?;
            let model = ReducemFile::open(&file)?;
            let up = overrides.up.unwrap_or_else(|| stored_up_axis(&model));
            render(
                &model,
                &prepare_scene(scene, &overrides, up)?,
                &destination,
                format,
                json,
            )
        }
    }
}

/// `reducem view`: the viewer is its own binary (its crate depends on this one), found beside
/// this executable, then on PATH; it replaces this process, so its exit code is the command's.
fn exec_viewer(args: Vec<std::ffi::OsString>) -> anyhow::Result<()> {
    use std::os::unix::process::CommandExt;
    let beside = std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.join("reducem-view")))
        .filter(|path| path.is_file());
    let program = beside.unwrap_or_else(|| PathBuf::from("reducem-view"));
    let error = std::process::Command::new(&program).args(args).exec();
    eprintln!(
        "reducem view needs the reducem-view binary: cargo install --locked --path view ({}: {error})",
        program.display()
    );
    std::process::exit(69)
}

/// The image format of the output argument: by its extension, else PNG for a stream (`-`,
/// `/dev/null`, a FIFO).
fn image_format(output: &Path) -> Result<ImageFormat, UsageError> {
    match ImageFormat::of(output) {
        Some(format) => Ok(format),
        None if reducem::output::is_stream(output) => Ok(ImageFormat::Png),
        None => Err(UsageError(format!(
            "output {}: unknown image format (the extension must be .png or .pfm)",
            output.display()
        ))),
    }
}

fn query(
    path: &Path,
    rays_path: &Path,
    output: &Destination,
    answer: Answer,
    invalid_rays: InvalidRays,
) -> anyhow::Result<()> {
    let kernel = Kernel::from_env()?;
    // Opening validates the model and maps the rays (checked as they are traced), together.
    let (rays, file) = rayon::join(
        || RayFile::open_checked_while_traced(rays_path, invalid_rays),
        || ReducemFile::open(path),
    );
    let (rays, file) = (rays?, file?);
    if let Some(first) = rays.first_invalid() {
        eprintln!(
            "reducem: query: {} invalid rays answered as misses (first: {first})",
            rays.invalid()
        );
    }
    file.advise_batch(rays.len() - rays.invalid());
    let options = TraceOptions {
        kernel,
        ..TraceOptions::default()
    };
    let (ray_count, invalid) = (rays.len(), rays.invalid());
    let answer_into = move |out: AnswerSink| {
        let tracer = Tracer::new(&file, options);
        let started = Instant::now();
        let hits = match out {
            AnswerSink::File(out) => ray_file::write_answers(&tracer, &rays, answer, out),
            AnswerSink::Stream(out) => {
                ray_file::write_answers_streamed(&tracer, &rays, answer, out)
            }
        };
        let hits = hits.map_err(|error| match ray_file::invalid_ray(error) {
            Ok(defect) => anyhow::Error::from(defect),
            Err(error) => error.into(),
        })?;
        let seconds = started.elapsed().as_secs_f64();
        // Answers of rays that met a corrupt part of the file are incomplete: nothing is
        // renamed into place (a stream has them, and the exit code says they are not all).
        complete(&file)?;
        anyhow::Ok((hits, seconds, unmap_behind(file, rays)))
    };
    let written = match output {
        Destination::Replace(path) => {
            atomic::write_atomically_with(path, |out| answer_into(AnswerSink::File(out.get_ref())))
        }
        stream => stream.write(|out| answer_into(AnswerSink::Stream(out))),
    };
    let (hits, seconds, unmapping) =
        written.map_err(
            |error| match error.is::<FormatError>() || error.is::<RayFileError>() {
                true => error,
                false => error.context(format!("writing {}", output.name())),
            },
        )?;
    let summary = QuerySummary {
        rays: ray_count,
        invalid,
        hits,
        seconds,
        kernel,
    };
    // One write: runs sharing a log (cron jobs) never interleave their summaries.
    let line = format!("{summary}\n");
    let _ = std::io::stderr().write_all(line.as_bytes());
    let _ = unmapping.join();
    Ok(())
}

/// Where `query` writes its answers: a regular file at each chunk's place, on every core, or a
/// stream in order.
enum AnswerSink<'a> {
    File(&'a std::fs::File),
    Stream(&'a mut dyn std::io::Write),
}

/// Unmaps the model and the rays on another thread, while the answers are synced and renamed
/// into place: after tracing 1M camera rays on the 10M scan in about 101 ms on 2 threads,
/// tearing down the model's mapped pages (190 MB file) took 6 ms, and the fsync and rename
/// 4 to 11 ms (the rename frees the replaced answers). Whole process: 113.8 -> 109.3 ms of
/// wall time, medians of 11 alternating runs.
fn unmap_behind(file: ReducemFile, rays: RayFile) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || drop((file, rays)))
}

/// The query's one summary line: `key=value` fields, so that scripts can parse it and later
/// fields can be appended without breaking them.
struct QuerySummary {
    rays: usize,
    invalid: usize,
    hits: usize,
    seconds: f64,
    kernel: Kernel,
}

impl std::fmt::Display for QuerySummary {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let traced = self.rays - self.invalid;
        let mrays = if self.seconds > 0.0 {
            traced as f64 / self.seconds / 1e6
        } else {
            0.0
        };
        write!(
            f,
            "reducem: query: rays={} invalid={} hits={} seconds={:.6} mrays_per_s={mrays:.3} \
             kernel={}",
            self.rays, self.invalid, self.hits, self.seconds, self.kernel
        )
    }
}

/// The up axis the file stores; z, as scenes are written, for a file that stores none.
fn stored_up_axis(file: &ReducemFile) -> UpAxis {
    match file.up_axis() {
        Some(reducem::format::model::UpAxis::Y) => UpAxis::Y,
        Some(reducem::format::model::UpAxis::Z) | None => UpAxis::Z,
    }
}

/// The scene turned for a model whose up axis is `up` and overridden as the command line asks;
/// an override that makes the scene invalid is a usage error.
fn prepare_scene(
    mut scene: Scene,
    overrides: &SceneOverrides,
    up: UpAxis,
) -> anyhow::Result<Scene> {
    if up == UpAxis::Y {
        scene.turn_to_y_up();
    }
    apply_overrides(&mut scene, overrides);
    scene.check().map_err(|(key, detail)| {
        UsageError(format!("the command line makes {key} invalid: {detail}"))
    })?;
    Ok(scene)
}

fn apply_overrides(scene: &mut Scene, overrides: &SceneOverrides) {
    let camera = &mut scene.camera;
    if let (Some(position), Some(look_at)) = (overrides.camera_position, overrides.look_at) {
        (camera.auto, camera.direction) = (false, None);
        (camera.position, camera.look_at) = (Some(position), Some(look_at));
    }
    camera.up = overrides.camera_up.unwrap_or(camera.up);
    camera.fov_degrees = overrides.fov.unwrap_or(camera.fov_degrees);
    scene.image.width = overrides.width.unwrap_or(scene.image.width);
    scene.image.height = overrides.height.unwrap_or(scene.image.height);
    scene.image.antialiasing = overrides.antialiasing.unwrap_or(scene.image.antialiasing);
    scene.shading.exposure = overrides.exposure.unwrap_or(scene.shading.exposure);
    match overrides.ao_samples {
        Some(0) => scene.ambient_occlusion = None,
        Some(samples) => scene.ambient_occlusion.get_or_insert_default().samples = samples,
        None => {}
    }
    if let Some(distance) = overrides.ao_distance {
        scene.ambient_occlusion.get_or_insert_default().max_distance = Some(distance);
    }
}

fn render(
    file: &ReducemFile,
    scene: &Scene,
    output: &Destination,
    format: ImageFormat,
    json: bool,
) -> anyhow::Result<()> {
    reducem::render::memory::check(scene, format).map_err(UsageError)?;
    let options = TraceOptions {
        kernel: Kernel::from_env()?,
        ..TraceOptions::default()
    };
    let tracer = Tracer::new(file, options);
    let report = output
        .write(|out| {
            let report = reducem::render::image::render_into(&tracer, scene, format, out).map_err(
                |source| ImageError {
                    path: output.name().into(),
                    source,
                },
            )?;
            // A render that met a corrupt part of the file is incomplete: nothing is renamed
            // into place.
            complete(file)?;
            anyhow::Ok(report)
        })
        .map_err(|error| match error.is::<std::io::Error>() {
            true => error.context(format!("writing {}", output.name())),
            false => error,
        })?;
    let text = match json {
        true => format!("{}\n", serde_json::to_string(&report)?),
        false => report.to_string(),
    };
    // Standard output carries the image, if that is where it goes.
    let written = match output.is_stdout() {
        true => std::io::stderr().write_all(text.as_bytes()),
        false => std::io::stdout().write_all(text.as_bytes()),
    };
    written.context("writing the report")
}

/// Fails when the traced rays met a corrupt strip or node of a lazily opened file: their
/// answers are incomplete, so nothing is written (exit code 65, naming the file and byte).
fn complete(file: &ReducemFile) -> Result<(), FormatError> {
    file.defect().map_or(Ok(()), Err)
}

fn inspect(path: &std::path::Path, json: bool, verify: bool) -> anyhow::Result<()> {
    // The statistics walk every strip anyway: validating them all first costs little more.
    let file = ReducemFile::open_with(path, Validation::Full)?;
    if verify {
        file.verify_checksums()?;
    }
    let stats = reducem::inspect::file_stats(&file);
    if json {
        println!("{}", serde_json::to_string(&stats)?);
        return Ok(());
    }
    println!("{}", path.display());
    println!(
        "  triangles          {} ({} dropped as degenerate)",
        stats.triangles, stats.dropped_triangles
    );
    println!(
        "  strips             {} (avg {:.2}, max {} triangles)",
        stats.strips, stats.avg_strip_length, stats.max_strip_length
    );
    println!(
        "  vertices           {} input, {} stored ({} for the strip hierarchies: {:.2}%)",
        stats.input_vertices,
        stats.stored_vertices,
        stats.hierarchy_vertices,
        stats.hierarchy_overhead_pct
    );
    println!(
        "  top level          {} nodes of {} children, {} bytes each",
        stats.top_nodes, stats.top_node_width, stats.top_node_bytes
    );
    println!(
        "  vertices stored as {}",
        match stats.grid_bits {
            0 => "f32 (lossless)".to_string(),
            bits => format!(
                "points of a {bits}-bit grid, cell {:e}{} (format {}, vertex_encoding {})",
                stats.grid_cell,
                match stats.vertex_encoding_value {
                    5 => ", in pools shared by consecutive strips",
                    _ => "",
                },
                stats.format_version,
                stats.vertex_encoding_value
            ),
        }
    );
    println!(
        "  position error     max {:.3e} ({:.3e} of the diagonal), rms {:.3e} ({:.3e})",
        stats.position_error_max,
        stats.position_error_max_relative,
        stats.position_error_rms,
        stats.position_error_rms_relative
    );
    if stats.weld_tolerance > 0.0 {
        println!(
            "  weld               {} vertices merged within {:e}: moved max {:.3e}, rms {:.3e}",
            stats.welded_vertices,
            stats.weld_tolerance,
            stats.weld_displacement_max,
            stats.weld_displacement_rms
        );
    }
    if stats.face_ids || stats.normals != "none" || stats.colors {
        println!(
            "  attributes         face ids {}, normals {} (max error {:.4} degrees), colours {}",
            if stats.face_ids { "yes" } else { "no" },
            stats.normals,
            stats.normal_error_max_degrees,
            if stats.colors { "yes" } else { "no" },
        );
    }
    println!(
        "  model              {}",
        reducem::inspect::model_line(&stats)
    );
    println!(
        "  file               {} bytes, {:.2} bytes/triangle",
        stats.file_bytes, stats.bytes_per_triangle
    );
    for (section, bytes) in &stats.bytes_by_section {
        println!(
            "    {section:<16} {bytes:>14} bytes  {:>6.2} B/tri",
            *bytes as f64 / stats.triangles.max(1) as f64
        );
    }
    if verify {
        println!("  checksums          ok");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    #[test]
    fn every_argument_of_every_command_has_a_description() {
        let undescribed = reducem::cli::undescribed_arguments(&super::Cli::command());
        assert!(undescribed.is_empty(), "no description: {undescribed:?}");
    }
}
