//! Runs ethercrab's futures on the calling thread, with no executor and no second
//! thread: poll the future, send the frames it queued through the raw socket, wait for
//! frames to come back, hand them to ethercrab, poll again.
//!
//! ethercrab's own `std` runner sends and receives in a thread of its own and wakes the
//! waiting future across threads: two thread hand-overs per exchange. Here the cycle
//! thread does both ends itself, so an exchange costs one frame's round trip on the wire
//! and nothing else. The waker is `Waker::noop()`: the loop polls again after every
//! frame it receives and at least every [`POLL_SLICE_NS`] (which is when ethercrab's
//! internal timers, checked on each poll, can fire), so nothing needs waking.
//! Nothing here allocates once the pump exists.

use std::future::Future;
use std::io;
use std::pin::pin;
use std::task::{Context, Poll, Waker};
use std::time::{Duration, Instant};

use ethercrab::{PduRx, PduTx, ReceiveAction};
use thiserror::Error;

use crate::socket::RawSocket;

/// Longest wait between two polls of a future while no frame arrives, ns: fine enough for
/// ethercrab's bring-up loops (which wait milliseconds between register reads).
pub const POLL_SLICE_NS: u64 = 100_000;

/// Largest Ethernet frame received (1514 bytes without the frame check sequence).
const FRAME_BYTES: usize = 1536;

/// Why a pumped exchange failed.
#[derive(Debug, Error)]
pub enum PumpError {
    /// The raw socket failed (interface down, removed, permission).
    #[error("EtherCAT interface {interface}: {source}")]
    Socket {
        /// The interface.
        interface: String,
        /// The operating system's error.
        #[source]
        source: io::Error,
    },
    /// ethercrab refused a frame to send or one received.
    #[error("EtherCAT frame: {0}")]
    Frame(ethercrab::error::Error),
    /// The future did not finish in time: frames were lost or the network did not answer.
    #[error("no answer from the EtherCAT network within {waited_us} µs")]
    Timeout {
        /// How long the pump waited, µs.
        waited_us: u64,
    },
}

/// Frames counted by the pump since it was made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameCounts {
    /// Frames sent.
    pub sent: u64,
    /// Frames received that belonged to an exchange in flight.
    pub received: u64,
    /// Frames received and ignored (our own frames looped back, other EtherTypes, late
    /// answers to an exchange already given up).
    pub ignored: u64,
}

/// The frame pump of one network interface.
pub struct Pump {
    socket: RawSocket,
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    frame: Box<[u8; FRAME_BYTES]>,
    counts: FrameCounts,
}

impl std::fmt::Debug for Pump {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pump")
            .field("interface", &self.socket.interface())
            .field("counts", &self.counts)
            .finish_non_exhaustive()
    }
}

impl Pump {
    /// A pump that moves the frames of `tx`/`rx` through `socket`.
    pub fn new(socket: RawSocket, tx: PduTx<'static>, rx: PduRx<'static>) -> Pump {
        Pump {
            socket,
            tx,
            rx,
            frame: Box::new([0; FRAME_BYTES]),
            counts: FrameCounts::default(),
        }
    }

    /// Frames counted so far.
    pub fn counts(&self) -> FrameCounts {
        self.counts
    }

    /// Runs `future` to completion on this thread, pumping its frames, or gives up after
    /// `timeout` (dropping the future, which releases its frames in ethercrab).
    pub fn block_on<F: Future>(
        &mut self,
        future: F,
        timeout: Duration,
    ) -> Result<F::Output, PumpError> {
        let started = Instant::now();
        let deadline = started + timeout;
        let mut future = pin!(future);
        let mut cx = Context::from_waker(Waker::noop());
        loop {
            if let Poll::Ready(output) = future.as_mut().poll(&mut cx) {
                return Ok(output);
            }
            self.send_queued()?;
            let now = Instant::now();
            if now >= deadline {
                return Err(PumpError::Timeout {
                    waited_us: u64::try_from(now.duration_since(started).as_micros())
                        .unwrap_or(u64::MAX),
                });
            }
            let left_ns = u64::try_from((deadline - now).as_nanos()).unwrap_or(u64::MAX);
            let ready = self
                .socket
                .wait_readable(left_ns.min(POLL_SLICE_NS))
                .map_err(|e| self.socket_error(e))?;
            if ready {
                self.receive_waiting()?;
            }
        }
    }

    /// Sends every frame ethercrab has queued.
    fn send_queued(&mut self) -> Result<(), PumpError> {
        while let Some(frame) = self.tx.next_sendable_frame() {
            let socket = &self.socket;
            let mut failure = None;
            let sent = frame.send_blocking(|bytes| match socket.send(bytes) {
                Ok(n) => Ok(n),
                Err(e) => {
                    failure = Some(e);
                    Err(ethercrab::error::Error::SendFrame)
                }
            });
            if let Some(e) = failure {
                return Err(self.socket_error(e));
            }
            sent.map_err(PumpError::Frame)?;
            self.counts.sent += 1;
        }
        Ok(())
    }

    /// Hands every frame waiting on the socket to ethercrab.
    fn receive_waiting(&mut self) -> Result<(), PumpError> {
        loop {
            let got = self
                .socket
                .recv(&mut self.frame[..])
                .map_err(|e| self.socket_error(e))?;
            let Some(len) = got else { return Ok(()) };
            match self.rx.receive_frame(&self.frame[..len]) {
                Ok(ReceiveAction::Processed) => self.counts.received += 1,
                // A late answer to an exchange already given up lands in a slot no longer
                // waiting for it: counted, not an error of this exchange.
                Ok(_) | Err(_) => self.counts.ignored += 1,
            }
        }
    }

    fn socket_error(&self, source: io::Error) -> PumpError {
        PumpError::Socket {
            interface: self.socket.interface().to_owned(),
            source,
        }
    }
}
