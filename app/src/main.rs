use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = previz::cli::Cli::parse();
    match previz::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
