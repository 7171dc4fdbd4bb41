fn main() -> std::process::ExitCode {
    // On an iPhone the binary is the app: the live window, no command line (live::ios).
    #[cfg(target_os = "ios")]
    return previz::live::ios::main_exit_code();
    #[allow(unreachable_code)]
    quiet_on_broken_pipe();
    let cli = previz::cli::parse();
    match previz::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // The reader of our output went away (`previz ... | head`): nothing left to tell anyone.
        Err(e) if is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Rust ignores SIGPIPE, so a write to a closed pipe fails with EPIPE and `println!` panics on
/// it. When stdout's reader has gone away the output is no longer wanted: exit quietly with
/// status 0 instead of printing a panic. Every other panic keeps the default report.
fn quiet_on_broken_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(0);
        }
        default(info);
    }));
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe))
}
