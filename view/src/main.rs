//! `reducem-view`, run as `reducem view FILE`: serves, on one address, a page that shows the file
//! traced on this machine, a coarse frame first and then the full one after every camera move.
//! Stdout carries exactly one line, the page's address with its token; logs go to stderr.

mod http;
mod jpeg;
mod resident;
mod session;
mod stages;
mod views;

use std::io::Write;
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;
use reducem::exit_code;
use reducem::format::reader::ReducemFile;
use reducem::render::scene::Scene;
use reducem::trace::{TraceOptions, Tracer};

use views::{UpAxis, Viewer};

#[derive(Parser)]
#[command(
    name = "reducem view",
    bin_name = "reducem view",
    version,
    about = "Serve an interactive view of a ReduceM file to a browser",
    after_help = exit_code::HELP
)]
struct Args {
    /// The ReduceM file.
    file: PathBuf,
    /// The address to listen on; port 0 picks a free port.
    #[arg(long, value_name = "ADDR:PORT", default_value = "127.0.0.1:0")]
    bind: String,
    /// The scene whose lights and effects shade the view (docs/SCENES.md); default
    /// configs/scenes/primary.toml.
    #[arg(long, value_name = "SCENE.toml")]
    scene: Option<PathBuf>,
    /// The model's up axis: scenes are written for z-up models and turned for y-up ones;
    /// default the axis stored in the file (`[input] up` at conversion), else y.
    #[arg(long, value_enum)]
    up: Option<UpAxis>,
    /// Threads that trace the frames; default all cores.
    #[arg(long)]
    threads: Option<usize>,
}

/// The scene the viewer shades with when none is given.
const DEFAULT_SCENE: &str = include_str!("../../configs/scenes/primary.toml");

fn main() -> ExitCode {
    if let Err(error) = install_signal_handlers() {
        eprintln!("reducem view: error: installing signal handlers: {error}");
        return ExitCode::from(exit_code::INTERNAL);
    }
    let args = match reducem::cli::parse_or_exit::<Args>() {
        Ok(args) => args,
        Err(code) => return code,
    };
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("reducem view: error: {error:#}");
            ExitCode::from(exit_code_of(&error))
        }
    }
}

/// SIGINT and SIGTERM end the server cleanly with 0 (the contract), after removing any
/// temporary this process named; a SIGBUS from a changed mapped file ends it with 74.
fn install_signal_handlers() -> std::io::Result<()> {
    reducem_core::signals::install_bus_handler()?;
    let mut signals = signal_hook::iterator::Signals::new([
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
    ])?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                reducem_core::signals::remove_own_temporaries();
                eprintln!("reducem view: signal {signal}, stopping");
                std::process::exit(0);
            }
        })?;
    Ok(())
}

fn exit_code_of(error: &anyhow::Error) -> u8 {
    for cause in error.chain() {
        if cause.is::<reducem::render::scene::SceneError>() {
            return exit_code::CONFIG;
        }
        if cause.is::<reducem::exit_code::UsageError>() {
            return exit_code::USAGE;
        }
        if let Some(error) = cause.downcast_ref::<reducem::format::reader::FormatError>() {
            return match error {
                reducem::format::reader::FormatError::Io { .. } => exit_code::IO,
                _ => exit_code::BAD_INPUT,
            };
        }
        if cause.is::<std::io::Error>() {
            return exit_code::IO;
        }
    }
    exit_code::INTERNAL
}

fn run(args: Args) -> anyhow::Result<()> {
    reducem::cli::check_mappable(&args.file)?;
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .thread_name(|index| format!("trace-{index}"))
        .build_global()
        .context("starting the tracing threads")?;
    let scene = load_scene(&args)?;
    // The server runs until a signal ends the process, so the file and its tracer live as long.
    let file: &'static ReducemFile = Box::leak(Box::new(ReducemFile::open(&args.file)?));
    let tracer: &'static Tracer = Box::leak(Box::new(Tracer::new(file, TraceOptions::default())));
    let listener = TcpListener::bind(&args.bind).map_err(|error| {
        reducem::exit_code::UsageError(format!("--bind {}: {error}", args.bind))
    })?;
    let address = listener.local_addr()?;
    let viewer = Viewer::new(tracer, scene, up_axis(&args, file), new_token()?);
    let viewer: &'static Viewer = Box::leak(Box::new(viewer));
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "http://{address}/?token={}", viewer.token)?;
    stdout.flush()?;
    drop(stdout);
    eprintln!(
        "reducem view: {} on http://{address}/ with {threads} tracing threads",
        args.file.display()
    );
    for connection in listener.incoming() {
        let Ok(stream) = connection else { continue };
        let spawned = std::thread::Builder::new()
            .name("connection".into())
            .spawn(move || http::serve(stream, viewer));
        if let Err(error) = spawned {
            eprintln!("reducem view: cannot serve a connection: {error}");
        }
    }
    Ok(())
}

/// The scene file, or the default one.
fn load_scene(args: &Args) -> anyhow::Result<Scene> {
    Ok(match &args.scene {
        Some(path) => Scene::load(path)?,
        None => Scene::parse(std::path::Path::new("primary.toml"), DEFAULT_SCENE)?,
    })
}

/// The model's up axis: the command line's, else the hint the file stores, else y.
fn up_axis(args: &Args, file: &ReducemFile) -> UpAxis {
    use reducem::format::model::UpAxis as Stored;
    args.up.unwrap_or(match file.up_axis() {
        Some(Stored::Z) => UpAxis::Z,
        Some(Stored::Y) | None => UpAxis::Y,
    })
}

/// 128 random bits in hex, URL-safe: the secret every request must carry.
fn new_token() -> anyhow::Result<String> {
    let mut bits = [0u8; 16];
    getrandom::fill(&mut bits).map_err(|error| anyhow::anyhow!("random token: {error}"))?;
    Ok(bits.iter().map(|byte| format!("{byte:02x}")).collect())
}
