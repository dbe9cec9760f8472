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
mod sweep;

use std::process::ExitCode;

use acdf::error::{Error, Result};
use clap::{Parser, Subcommand};

/// Importance sampling of measured BRDFs with adaptive numerical CDFs.
#[derive(Parser, Debug)]
#[command(name = "acdf", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
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
    /// The results table: storage, compression and estimator efficiency of
    /// every sampler, per material.
    Report(report::Args),
    /// Efficiency against storage for each simplifier over a range of
    /// tolerances: CSV on stdout, CSV/JSON/SVG/PNG in the output directory.
    Sweep(sweep::Args),
    /// Render a sphere lit by an environment with each sampler and compare
    /// with a high-count reference.
    Render(render::Args),
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
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        // A closed pipe (e.g. `acdf sample ... | head`) is not a failure.
        Err(Error::Stream(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("acdf: error: {e}");
            ExitCode::FAILURE
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
        Command::Render(a) => render::run(a),
        Command::Bench(a) => bench::run(a),
        Command::EnvSample(a) => env_sample::run(a),
        Command::EnvPdf(a) => env_pdf::run(a),
        Command::EnvReport(a) => env_report::run(a),
    }
}
