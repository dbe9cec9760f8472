//! The `acdf` command: draw samples, evaluate densities and BRDFs, bake
//! Neural-BRDF networks into MERL files, and run the experiments (results
//! table, tolerance sweep, sphere renders). Every failure is one line on
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
mod eval;
mod pdf;
mod render;
mod report;
mod sample;
mod survey;
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
    /// Every sampler on all 100 MERL materials against the seed's
    /// 32x16x256x32 table: CSV, JSON, a scatter plot (SVG, PNG) of
    /// compression against relative efficiency, and a summary table.
    #[command(after_long_help = survey::COLUMNS)]
    Survey(survey::Args),
    /// Render a sphere lit by an environment with each sampler and compare
    /// with a high-count reference.
    Render(render::Args),
    /// Sampling throughput (samples per second) of the 2D distributions and
    /// the BRDF samplers, and the build time of the 4D tables; a table on
    /// stdout, optionally JSON.
    Bench(bench::Args),
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
        Command::Survey(a) => survey::run(a),
        Command::Render(a) => render::run(a),
        Command::Bench(a) => bench::run(a),
    }
}
