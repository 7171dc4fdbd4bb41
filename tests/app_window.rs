//! The window shell (`live::window::Shell`) under Xvfb, driven through winit the way a phone
//! drives it: the test's own winit handler forwards every event to the shell and, on the test's
//! commands (sent through the event loop's proxy), delivers winit's `suspended` and `resumed`
//! events to it — what Android sends when the activity goes to the background and comes back.
//! It checks that the shell drops the window's surface and pauses the app on `suspended`, draws
//! nothing while suspended, and on `resumed` makes a new surface and presents again with the
//! same app (its clock moves on, the model stays where it was). Every step waits for what the
//! shell reports (first presented frame, the next frame after resume), never for a fixed time.
//! Alone in its test binary: winit allows one event loop per process.

mod common;

use common::scene;
use previz::live::app::App;
use previz::live::window::Shell;
use previz::live::{LiveConfig, LiveSession};
use previz::sensors::sim::NoiseLevel;
use previz::setup::load_inputs;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Duration;
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop, EventLoopProxy};
use winit::platform::x11::EventLoopBuilderExtX11;
use winit::window::WindowId;

/// What the test asks the platform side to do.
#[derive(Debug)]
enum Command {
    /// Deliver winit's `suspended` event (the activity stopped, the screen locked).
    Suspend,
    /// Deliver winit's `resumed` event (back in the foreground).
    Resume,
    /// Ask the window for a redraw (the window exposed again).
    Redraw,
    Quit,
}

/// What the shell looked like after an event.
#[derive(Clone, Debug)]
struct Report {
    after: &'static str,
    presented: usize,
    surface: bool,
    suspended: bool,
    t: Option<f64>,
    position: Option<glam::Vec3>,
}

struct Driver {
    shell: Shell,
    reports: Sender<Report>,
}

impl Driver {
    fn report(&self, after: &'static str) {
        let app = self.shell.app();
        let _ = self.reports.send(Report {
            after,
            presented: self.shell.presented_frames(),
            surface: self.shell.has_surface(),
            suspended: app.is_some_and(|a| a.session().is_suspended()),
            t: app.and_then(|a| a.last_frame()).map(|f| f.t),
            position: app.map(|a| a.session().params().placement.position),
        });
    }
}

impl ApplicationHandler<Command> for Driver {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        self.shell.resumed(el);
        self.report("resumed");
    }

    fn suspended(&mut self, el: &ActiveEventLoop) {
        self.shell.suspended(el);
        self.report("suspended");
    }

    fn window_event(&mut self, el: &ActiveEventLoop, id: WindowId, event: WindowEvent) {
        let redraw = matches!(event, WindowEvent::RedrawRequested);
        self.shell.window_event(el, id, event);
        if redraw {
            self.report("redraw");
        }
    }

    fn user_event(&mut self, el: &ActiveEventLoop, command: Command) {
        match command {
            Command::Suspend => self.suspended(el),
            Command::Resume => self.resumed(el),
            Command::Redraw => self.shell.request_redraw(),
            Command::Quit => el.exit(),
        }
    }
}

/// Sends `Quit` when dropped, so a failing driver ends the event loop instead of hanging it.
struct QuitOnDrop(EventLoopProxy<Command>);

impl Drop for QuitOnDrop {
    fn drop(&mut self) {
        let _ = self.0.send_event(Command::Quit);
    }
}

/// The next report satisfying `want` (a generous deadline guards against a hung loop).
fn wait_for(reports: &Receiver<Report>, what: &str, want: impl Fn(&Report) -> bool) -> Report {
    loop {
        match reports.recv_timeout(Duration::from_secs(120)) {
            Ok(r) if want(&r) => return r,
            Ok(_) => {}
            Err(e) => panic!("waiting for {what}: {e}"),
        }
    }
}

/// The platform side: waits for the first presented frame, then two suspend → resume cycles.
fn drive(proxy: EventLoopProxy<Command>, reports: Receiver<Report>) -> usize {
    let quit = QuitOnDrop(proxy.clone());
    let send = |c: Command| proxy.send_event(c).expect("the event loop is running");
    let first = wait_for(&reports, "the first presented frame", |r| r.presented >= 1);
    let position = first.position.expect("the app exists once a frame is presented");
    let mut last = first;
    for cycle in 0..2 {
        send(Command::Suspend);
        let s = wait_for(&reports, "the suspension", |r| r.after == "suspended");
        assert!(!s.surface, "cycle {cycle}: the surface is dropped on suspend");
        assert!(s.suspended, "cycle {cycle}: the app's camera and sensors are stopped");
        // A redraw while suspended draws and presents nothing.
        send(Command::Redraw);
        let r = wait_for(&reports, "a redraw while suspended", |r| r.after == "redraw");
        assert!(r.suspended && !r.surface);
        assert_eq!(r.presented, s.presented, "cycle {cycle}: a frame was presented while suspended");
        assert_eq!(r.t, s.t, "cycle {cycle}: the session advanced while suspended");
        send(Command::Resume);
        let r = wait_for(&reports, "the resumption", |r| r.after == "resumed");
        assert!(r.surface, "cycle {cycle}: a new surface on resume");
        assert!(!r.suspended, "cycle {cycle}: camera and sensors started again");
        // The resumed window presents again, with the same app.
        let next = wait_for(&reports, "a frame after resuming", |r| r.presented > s.presented);
        assert!(next.t > last.t, "cycle {cycle}: the session's clock moves on ({:?} after {:?})", next.t, last.t);
        assert_eq!(next.position, Some(position), "cycle {cycle}: the model stays where it was");
        last = next;
    }
    drop(quit);
    last.presented
}

#[test]
fn suspend_and_resume_drop_and_recreate_the_window_surface_under_xvfb() {
    let xvfb = common::xvfb::Xvfb::start(320, 240);
    // The only test in this binary, before any other thread reads the environment: winit
    // connects to Xvfb's display (X11, not a Wayland compositor the machine may have).
    unsafe {
        std::env::set_var("DISPLAY", &xvfb.display);
        std::env::remove_var("WAYLAND_DISPLAY");
    }
    let s = scene("width = 160\nheight = 120\nmodel = \"meshes/icosphere-320.obj\"\nenvironment = \"cubemaps/humus_Park2_512\"\n");
    let cfg = LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T12:00:00Z").unwrap().with_timezone(&chrono::Utc),
        frame_hz: 15.0,
        duration_s: 600.0,
        noise: NoiseLevel::None,
        seed: 1,
    };
    let export = common::cli::tempdir("app_window", "shell");
    let make = Box::new(move |gpu: &previz::gpu::Gpu| {
        let inputs = load_inputs(&s, false)?;
        let session = LiveSession::simulated(gpu, Arc::new(inputs.env), &inputs.model, &s, cfg)?;
        Ok(App::new(session, export))
    });
    let event_loop = EventLoop::<Command>::with_user_event().with_x11().with_any_thread(true).build().expect("an X11 event loop on Xvfb");
    let (tx, rx) = channel();
    let proxy = event_loop.create_proxy();
    let driver = std::thread::spawn(move || drive(proxy, rx));
    let mut handler = Driver { shell: Shell::new("previz test", (160, 120), make), reports: tx };
    event_loop.run_app(&mut handler).expect("the event loop ran");
    handler.shell.finish().expect("the shell ran without an error");
    let presented = driver.join().expect("the suspend/resume cycles passed");
    assert!(presented >= 3, "{presented} frames presented");
}
