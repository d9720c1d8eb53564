//! Setpoint publishing off the real-time thread.
//!
//! iceoryx2 0.10 allocates on every publish: `Publisher::send_copy` loans a sample, and
//! each loan boxes a reference-counted handle of the sample's shared state (`Rc::new` in
//! `loan_uninit`); connecting a new subscriber allocates again on the next publish. The
//! cycle must not allocate, so it pushes each setpoint (with the time it pushed it) into
//! a preallocated lock-free ring and wakes a helper thread (`Thread::unpark`: an atomic
//! and, when the helper sleeps, one futex wake-up; no allocation, no lock), which
//! publishes. The helper runs one SCHED_FIFO priority below the cycle (when the cycle
//! has real-time scheduling), so it publishes as soon as the cycle sleeps.
//!
//! The helper keeps a histogram of the added latency (push to after `send_copy`) for the
//! log. A helper that falls a whole ring behind loses setpoints (counted; readers see the
//! gap in the sequence numbers), the cycle never waits.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use kerf_proto::SetpointMsg;

use super::timing::Histogram;
use crate::ipc;

/// Setpoints the ring to the helper holds: a quarter of a second at 4 kHz.
pub(crate) const SETPOINT_RING: usize = 1024;

/// The longest the helper sleeps without being woken (it checks its stop flag).
const IDLE_WAIT: Duration = Duration::from_millis(20);

/// The cycle's end of the ring.
pub struct SetpointOut {
    ring: rtrb::Producer<(SetpointMsg, u64)>,
    helper: std::thread::Thread,
    dropped: u64,
}

impl SetpointOut {
    /// Hands one setpoint to the helper and wakes it; `false` (and counted) if the ring
    /// was full. Never allocates, locks or blocks.
    pub fn push(&mut self, msg: SetpointMsg) -> bool {
        let ok = self.ring.push((msg, kerf_rt::now_ns())).is_ok();
        if !ok {
            self.dropped += 1;
        }
        self.helper.unpark();
        ok
    }

    /// Setpoints lost because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

/// The helper thread that publishes.
pub struct PublishThread {
    handle: Option<JoinHandle<Histogram>>,
    stop: Arc<AtomicBool>,
}

impl PublishThread {
    /// Publishes what is left, stops the helper, and returns its histogram of the added
    /// latency (push to after `send_copy`).
    pub fn finish(mut self) -> Option<Histogram> {
        let handle = self.handle.take()?;
        self.stop.store(true, Ordering::Release);
        handle.thread().unpark();
        handle.join().ok()
    }
}

impl Drop for PublishThread {
    /// A helper not finished (the cycle failed to start) stops on its own.
    fn drop(&mut self) {
        if let Some(handle) = &self.handle {
            self.stop.store(true, Ordering::Release);
            handle.thread().unpark();
        }
    }
}

/// Starts the helper: it creates the setpoints service of `machine` and its publisher
/// before this returns. `rt`: the helper's own real-time set-up, if any (failures are
/// ignored: the cycle's set-up reports them).
pub fn spawn(
    machine: &str,
    rt: Option<kerf_rt::RtConfig>,
) -> Result<(SetpointOut, PublishThread), String> {
    let (tx, rx) = rtrb::RingBuffer::<(SetpointMsg, u64)>::new(SETPOINT_RING);
    let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(), String>>();
    let stop = Arc::new(AtomicBool::new(false));
    let machine = machine.to_string();
    let helper_stop = stop.clone();
    let handle = std::thread::Builder::new()
        .name("kerfd-publish".to_string())
        .spawn(move || publish_thread(&machine, rt, ready_tx, helper_stop, rx))
        .map_err(|e| format!("cannot start the setpoint publisher thread: {e}"))?;
    match ready_rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(e),
        Err(_) => return Err("the setpoint publisher thread ended".to_string()),
    }
    let out = SetpointOut {
        ring: tx,
        helper: handle.thread().clone(),
        dropped: 0,
    };
    Ok((
        out,
        PublishThread {
            handle: Some(handle),
            stop,
        },
    ))
}

fn publish_thread(
    machine: &str,
    rt: Option<kerf_rt::RtConfig>,
    ready: std::sync::mpsc::Sender<Result<(), String>>,
    stop: Arc<AtomicBool>,
    mut ring: rtrb::Consumer<(SetpointMsg, u64)>,
) -> Histogram {
    let mut added = Histogram::new();
    let setup = || -> Result<_, ipc::IpcError> {
        let node = ipc::node("kerfd-publish")?;
        let service = ipc::create_setpoints(&node, machine)?;
        let publisher = service
            .publisher_builder()
            .create()
            .map_err(|e| ipc::IpcError::refused("cannot publish setpoints", e))?;
        Ok((node, service, publisher))
    };
    let (_node, _service, publisher) = match setup() {
        Ok(ports) => ports,
        Err(e) => {
            let _ = ready.send(Err(e.to_string()));
            return added;
        }
    };
    if let Some(rt) = rt {
        let _ = kerf_rt::rt_setup(&rt);
    }
    let _ = ready.send(Ok(()));
    loop {
        while let Ok((msg, pushed_ns)) = ring.pop() {
            // A slow or absent reader never blocks: safe overflow drops its oldest sample.
            let _ = publisher.send_copy(msg);
            added.record(kerf_rt::now_ns().saturating_sub(pushed_ns));
        }
        if stop.load(Ordering::Acquire) && ring.is_empty() {
            return added;
        }
        std::thread::park_timeout(IDLE_WAIT);
    }
}
