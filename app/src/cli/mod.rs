//! The command line: one file per subcommand, each with its clap `Args` and a `run` function.
//! `main.rs` only parses and reports errors.

use clap::{Parser, Subcommand};

pub mod bench;
pub mod capture;
pub mod colour_transfer;
pub mod composite;
pub mod live;
pub mod pose_stability;
pub mod priors;
pub mod sun;

#[derive(Parser, Debug)]
#[command(name = "previz", version, about = "AR compositing: a 3D model lit by the real sun, over a photograph or a live camera")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Composite a lit model over a background (no arguments: the bundled demo scene).
    Composite(composite::Args),
    /// Benchmarks (results recorded in docs/PERFORMANCE.md).
    Bench(bench::Args),
    /// Give TARGET the colour statistics of SOURCE (Reinhard / CIELAB-approx / MKL /
    /// brightness-contrast); `colour-transfer bench` measures every method.
    ColourTransfer(colour_transfer::Args),
    /// Print the colour priors of an environment (and a model); `priors bench` times CPU vs GPU.
    Priors(priors::Args),
    /// Sun position for a place and time (NREL SPA and cheaper algorithms), a photo, or a CSV.
    Sun(sun::Args),
    /// Measure the pose filter on simulated sensors: sun jitter while held still, lag in a
    /// turn, headings across 0/360°, pitch ±90°, magnetic disturbance (CSV + chart).
    PoseStability(pose_stability::Args),
    /// Replay a trace (or a simulated user) through the virtual phone into the cube-map capture
    /// assistant and write the capture folder; `capture stability` runs the stability study.
    Capture(capture::Args),
    /// The live view: virtual phone + simulated sensors + pose fusion + sun + compositor, in a
    /// window (or headless with --frames N -o DIR).
    Live(live::Args),
}

/// Parse the process's command line. Every command and subcommand takes negative numbers as
/// values, so `--width -1` or `--fps -5` get an error naming the flag and its range instead of
/// "unexpected argument '-1'".
pub fn parse() -> Cli {
    use clap::{CommandFactory, FromArgMatches};
    let matches = with_negative_numbers(Cli::command()).get_matches();
    Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}

fn with_negative_numbers(command: clap::Command) -> clap::Command {
    command.allow_negative_numbers(true).mut_subcommands(with_negative_numbers)
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Composite(a) => composite::run(a),
        Command::Bench(a) => bench::run(a),
        Command::ColourTransfer(a) => colour_transfer::run(a),
        Command::Priors(a) => priors::run(a),
        Command::Sun(a) => sun::run(a),
        Command::PoseStability(a) => pose_stability::run(a),
        Command::Capture(a) => capture::run(a),
        Command::Live(a) => live::run(a),
    }
}
