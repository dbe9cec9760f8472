//! The `acdf` command: draw samples, evaluate densities and BRDFs, bake
//! Neural-BRDF networks into MERL files, and run the experiments (results
//! table, tolerance sweep, sphere renders); the same for environment maps
//! (`env-sample`, `env-pdf`, `env-report`). Every failure is one line on
//! stderr and exit status 1.
//!
//! One module per subcommand, each with its arguments (`Args`) and its
//! `run`; [`common`] holds the argument groups and helpers they share. The
//! measurements themselves live in the library, so that tests and other
//! tools call the same code; `bench`'s are a module of the binary, so that
//! the library's public surface does not grow by them.
//!
//! Output never panics: the macros below replace the standard `print!`,
//! `println!`, `eprint!` and `eprintln!` in every module of the binary
//! (they are defined before the modules, so they shadow the standard ones
//! there). A closed standard output ends the command as it ends any Unix
//! tool, by SIGPIPE; any other failure to write it (a full disk) ends it
//! with one line on stderr and status 1; a failure to write stderr is
//! ignored, since there is nowhere left to report it.

/// `print!` that never panics; see the crate documentation.
#[allow(unused_macros)]
macro_rules! print {
    ($($arg:tt)*) => {
        $crate::print_or_exit(format_args!($($arg)*))
    };
}

/// `println!` that never panics; see the crate documentation.
#[allow(unused_macros)]
macro_rules! println {
    () => {
        $crate::print_or_exit(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::print_or_exit(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprint!` that ignores a failure to write stderr.
#[allow(unused_macros)]
macro_rules! eprint {
    ($($arg:tt)*) => {
        $crate::eprint_lossy(format_args!($($arg)*))
    };
}

/// `eprintln!` that ignores a failure to write stderr.
#[allow(unused_macros)]
macro_rules! eprintln {
    ($($arg:tt)*) => {
        $crate::eprint_lossy(format_args!("{}\n", format_args!($($arg)*)))
    };
}

mod bake;
mod bench;
mod build;
mod common;
mod env_common;
mod env_pdf;
mod env_report;
mod env_sample;
mod eval;
mod pdf;
mod render;
mod report;
mod sample;
mod survey;
mod sweep;

use std::io::Write;
use std::process::ExitCode;

use acdf::error::{Error, Result};
use clap::{Parser, Subcommand};

/// Importance sampling of measured BRDFs with adaptive numerical CDFs.
#[derive(Parser, Debug)]
#[command(name = "acdf", version, about, long_about = None)]
struct Cli {
    /// The most memory one table, image or file read may take, checked
    /// before it is allocated: bytes, or a number with K, M, G or T
    /// (powers of 1024), or `unlimited`.
    #[arg(long, global = true, value_name = "SIZE", default_value = "4G", value_parser = acdf_io::limits::parse_size)]
    memory_limit: u64,
    #[command(subcommand)]
    command: Command,
}

/// Write to stdout; on failure end the process (see the crate
/// documentation). Used by the `print!` and `println!` of this binary.
fn print_or_exit(args: std::fmt::Arguments<'_>) {
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        exit_on_output_error(&e);
    }
}

/// Write to stderr, ignoring failure. Used by the `eprint!` and
/// `eprintln!` of this binary.
fn eprint_lossy(args: std::fmt::Arguments<'_>) {
    let _ = std::io::stderr().lock().write_fmt(args);
}

/// End the command after standard output failed: by SIGPIPE for a closed
/// pipe, with one line and status 1 otherwise.
fn exit_on_output_error(e: &std::io::Error) -> ! {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        acdf_io::fsio::die_of_broken_pipe();
    }
    eprint_lossy(format_args!(
        "acdf: error: cannot write to standard output: {e}\n"
    ));
    std::process::exit(1)
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Draw incident directions for one outgoing direction; CSV on stdout
    /// (`wi_x,wi_y,wi_z,pdf,valid`, a failed draw is `0,0,0,0,0`).
    Sample(sample::Args),
    /// Print the sampler's solid-angle pdf for each `x,y,z` line of stdin.
    Pdf(pdf::Args),
    /// Print f_r (1/sr) as `r,g,b` for each `x,y,z` line of stdin.
    Eval(eval::Args),
    /// Bake a material (normally `nbrdf:NAME`) into a MERL `.binary` file.
    Bake(bake::Args),
    /// Build a tabulated sampler (uniform or adaptive) and save it to a file
    /// that `--sampler-file` loads without rebuilding.
    Build(build::Args),
    /// The results table: storage, compression, noise-free relative
    /// variance, firefly measure and efficiency of every sampler, per
    /// material.
    #[command(after_long_help = report::COLUMNS)]
    Report(report::Args),
    /// Efficiency against storage for every sampler, each simplifier over a
    /// range of tolerances: CSV on stdout, CSV/JSON/SVG/PNG in the output
    /// directory.
    #[command(after_long_help = report::COLUMNS)]
    Sweep(sweep::Args),
    /// Every sampler on all 100 MERL materials against the 32x16x256x32
    /// table of Lawrence et al.: CSV, JSON, a scatter plot (SVG, PNG) of
    /// compression against relative efficiency, and a summary table.
    #[command(after_long_help = survey::COLUMNS)]
    Survey(survey::Args),
    /// Render a sphere under an environment map with BRDF, light and MIS
    /// sampling and compare with a reference, or export the scene for
    /// Mitsuba 3.
    Render(Box<render::Args>),
    /// Sampling throughput (samples per second) of the 2D distributions and
    /// the BRDF samplers, and the build time of the 4D tables; a table on
    /// stdout, optionally JSON.
    Bench(bench::Args),
    /// Draw directions towards an environment map with an environment
    /// sampler; CSV on stdout (`x,y,z,pdf`, a failed draw is `0,0,0,0`).
    EnvSample(env_sample::Args),
    /// Print an environment sampler's solid-angle pdf for each `x,y,z` line
    /// of stdin.
    EnvPdf(env_pdf::Args),
    /// Storage, irradiance variance, time and efficiency of the environment
    /// samplers on each map: a table, optionally JSON and an SVG plot.
    EnvReport(env_report::Args),
}

fn main() -> ExitCode {
    // A bug should still be one line on stderr, not a backtrace.
    // Writing stderr must not panic inside the hook either: that aborts.
    std::panic::set_hook(Box::new(|info| {
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "acdf: internal error{place}: {}",
            message.replace('\n', " ")
        );
    }));
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return parse_failure(e),
    };
    acdf_io::limits::set_memory_limit(cli.memory_limit);
    // Ctrl-C or a kill during a write removes the temporary file.
    if let Err(e) = acdf_io::fsio::install_interrupt_cleanup() {
        eprintln!("acdf: warning: no interrupt handler ({e}); an interrupted write may leave a temporary file");
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Error::Stream(e)) => exit_on_output_error(&e),
        Err(e) => {
            eprintln!("acdf: error: {}", acdf::error::one_line(&e.to_string()));
            ExitCode::FAILURE
        }
    }
}

/// What a command line that does not run a subcommand ends with: the help
/// or version asked for, on standard output, written as every other output
/// is (a full disk is an error, not a silent success); or clap's usage
/// error, on stderr, with clap's status.
fn parse_failure(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    match e.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
            print_or_exit(format_args!("{}", e.render()));
            ExitCode::SUCCESS
        }
        _ => {
            eprint_lossy(format_args!("{}", e.render()));
            ExitCode::from(e.exit_code().clamp(0, 255) as u8)
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Sample(a) => sample::run(a),
        Command::Pdf(a) => pdf::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Bake(a) => bake::run(a),
        Command::Build(a) => build::run(a),
        Command::Report(a) => report::run(a),
        Command::Sweep(a) => sweep::run(a),
        Command::Survey(a) => survey::run(a),
        Command::Render(a) => render::run(*a),
        Command::Bench(a) => bench::run(a),
        Command::EnvSample(a) => env_sample::run(a),
        Command::EnvPdf(a) => env_pdf::run(a),
        Command::EnvReport(a) => env_report::run(a),
    }
}
