//! A virtual X server for the window tests (CI installs Xvfb: `.ci/run`).

use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// An Xvfb server on a display it picked itself; killed when dropped.
pub struct Xvfb {
    child: Child,
    /// The display to connect to, e.g. ":3".
    pub display: String,
}

impl Xvfb {
    /// Start Xvfb with one `width`×`height` screen and wait until it accepts connections:
    /// `-displayfd` makes it write the display's number once it is ready, so the wait is for
    /// exactly that (a generous deadline guards against a hung server), never a fixed time.
    pub fn start(width: u32, height: u32) -> Xvfb {
        let mut child = Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", &format!("{width}x{height}x24"), "-nolisten", "tcp"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb (apt-get install xvfb; .ci/run installs it)");
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line);
            let _ = tx.send(line);
        });
        let number = rx.recv_timeout(Duration::from_secs(60)).expect("Xvfb did not report a display within 60 s");
        let number: u32 = number.trim().parse().unwrap_or_else(|_| panic!("Xvfb exited before it was ready (it printed {number:?})"));
        Xvfb { child, display: format!(":{number}") }
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
