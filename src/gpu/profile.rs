//! Per-kernel time of a filter run (`noisefree filter --profile`): while a recording is open,
//! every launch through [`super::enqueue`] / [`super::enqueue_rows`] (and the few launches
//! that build their own command and call [`record`]) keeps its kernel's name and profiling
//! event; [`finish`] waits for them and sums the kernel time per name. So the split of a
//! filter's time between its kernels is a command anyone can run again, not a temporary print.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Result;
use ocl::Event;

/// The launches recorded since [`start`], `None` while no recording is open. A global, not a
/// thread-local, because a filter may launch from worker threads (several devices per frame).
static RECORDING: Mutex<Option<Vec<(String, Event)>>> = Mutex::new(None);

/// Whether a recording is open: every launch reads it, and only takes the lock when it is set.
static OPEN: AtomicBool = AtomicBool::new(false);

fn recording() -> std::sync::MutexGuard<'static, Option<Vec<(String, Event)>>> {
    // A panic elsewhere while holding the lock leaves a list that is still valid.
    RECORDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// Opens a recording (dropping any unfinished one).
pub fn start() {
    *recording() = Some(Vec::new());
    OPEN.store(true, Ordering::Release);
}

/// Keeps `event` of a launch of `kernel` if a recording is open; one atomic load otherwise.
pub fn record(kernel: &ocl::Kernel, event: &Event) {
    if !OPEN.load(Ordering::Acquire) {
        return;
    }
    let mut r = recording();
    if let Some(list) = r.as_mut() {
        let name = kernel.name().unwrap_or_else(|_| "(unnamed kernel)".into());
        list.push((name, event.clone()));
    }
}

/// One kernel's share of a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelTime {
    pub kernel: String,
    pub launches: usize,
    pub time: Duration,
}

/// Closes the recording: each kernel's launches and summed kernel time (from the profiling
/// events), in order of first launch. Empty when no recording was open.
pub fn finish() -> Result<Vec<KernelTime>> {
    let list = {
        let mut r = recording();
        OPEN.store(false, Ordering::Release);
        r.take().unwrap_or_default()
    };
    let mut order: Vec<KernelTime> = Vec::new();
    let mut index = BTreeMap::new();
    for (kernel, event) in list {
        let time = super::event_duration(&event)?;
        let i = *index.entry(kernel.clone()).or_insert_with(|| {
            order.push(KernelTime {
                kernel,
                launches: 0,
                time: Duration::ZERO,
            });
            order.len() - 1
        });
        order[i].launches += 1;
        order[i].time += time;
    }
    Ok(order)
}
