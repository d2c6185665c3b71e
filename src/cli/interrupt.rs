//! Ctrl-C during a render: the render loop stops after the launch in flight, and the render
//! writes nothing (exit status 130) unless `--save-partial` asks for what was rendered.

use std::sync::atomic::{AtomicBool, Ordering};

/// Set by the Ctrl-C handler; the render loop stops after the launch in flight.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// The error of a render stopped by Ctrl-C without --save-partial (exit status 130).
#[derive(Debug)]
pub struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "interrupted: nothing was written (use --save-partial to keep what was rendered)"
        )
    }
}

impl std::error::Error for Interrupted {}

/// Installs the Ctrl-C handler once per process.
pub fn catch_ctrl_c() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // If another handler is already installed, Ctrl-C keeps its default meaning.
        let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::SeqCst));
    });
}

pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}
