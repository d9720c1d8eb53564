//! The client side of the daemon's services: requests on the control service, and a
//! setpoint reader that checks the sequence (the status as `kerf status` prints it is in
//! [`crate::status_view`]).

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use kerf_proto::{ControlCommand, MoveMsg, REASON_OK, Request, Response, SetpointMsg, StatusMsg};

use kerfd::ipc;

pub use kerfd::fault_text::safety_text;

/// How long a request may go unanswered before the daemon counts as absent.
pub(crate) const REQUEST_TIMEOUT: Duration = Duration::from_secs(1);

/// How long the setpoint stream may stall before the daemon counts as gone: a hundred
/// cycles at the longest period the daemon runs would be a second; the stream never
/// pauses, so 100 ms is many cycles at any period up to 10 ms.
pub const STREAM_TIMEOUT: Duration = Duration::from_millis(100);

/// Why talking to the daemon failed.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// No daemon answers for the machine.
    #[error(
        "no kerfd answers for machine `{machine}`; start one with `kerfd --config FILE` (or `systemctl start kerfd`), or run the program with `kerf run --embedded`"
    )]
    NoDaemon {
        /// The machine name from the configuration.
        machine: String,
    },
    /// The daemon refused the request.
    #[error("{0}")]
    Refused(String),
    /// The daemon stopped while we were talking to it.
    #[error("kerfd for machine `{machine}` stopped: {detail}")]
    Gone {
        /// The machine name.
        machine: String,
        /// What was noticed.
        detail: String,
    },
    /// Shared memory could not be used.
    #[error("{0}")]
    Ipc(String),
    /// A node, service or port of the machine's services could not be made.
    #[error("{0}")]
    Service(#[from] ipc::IpcError),
}

/// A connection to one machine's daemon.
pub struct Client {
    machine: String,
    node: Node<ipc::Ipc>,
    _control: ipc::ControlService,
    client: iceoryx2::port::client::Client<ipc::Ipc, Request, (), Response, ()>,
    next_id: u64,
    /// The control wake-ups: `None` if they could not be opened (then the client polls).
    wake: Option<Wake>,
}

/// A client's ends of the control event services (see [`ipc::ControlEvents`]).
struct Wake {
    _events: ipc::ControlEvents,
    /// Tells the daemon a request was sent.
    request: iceoryx2::port::notifier::Notifier<ipc::Ipc>,
    /// Woken when the daemon has sent an answer (to this client or another).
    answer: iceoryx2::port::listener::Listener<ipc::Ipc>,
}

impl Wake {
    fn open(node: &Node<ipc::Ipc>, machine: &str) -> Option<Wake> {
        let events = ipc::open_control_events(node, machine).ok()?;
        let request = events.request.notifier_builder().create().ok()?;
        let answer = events.answer.listener_builder().create().ok()?;
        Some(Wake {
            _events: events,
            request,
            answer,
        })
    }
}

/// How long a waiting client sleeps between looks for its answer when it cannot be woken
/// (the event services could not be opened), and at most while it can.
const ANSWER_POLL: Duration = Duration::from_micros(200);

impl Client {
    /// Connects to the daemon of `machine` and checks that it answers.
    ///
    /// When the iceoryx2 files belong to another user, the error says so instead: the
    /// user the machine's daemon runs as (run the command as that user), or the owner of
    /// the tree ([`ipc::owner::client_diagnosis`]); never that no daemon answers while one
    /// of another user serves the machine. That is checked before the node is created, so
    /// that root never leaves files in another user's tree that its daemon cannot use.
    pub fn connect(machine: &str) -> Result<Client, ClientError> {
        if let Some(why) = ipc::owner::client_refusal(machine) {
            return Err(ClientError::Ipc(why));
        }
        let explained = |e: ClientError| match ipc::owner::client_diagnosis(machine) {
            Some(why) => ClientError::Ipc(why),
            None => e,
        };
        let node = ipc::node(&format!("kerf-{}", std::process::id()))
            .map_err(|e| explained(ClientError::Service(e)))?;
        let no_daemon = || ClientError::NoDaemon {
            machine: machine.to_string(),
        };
        let control = ipc::open_control(&node, machine).map_err(|_| explained(no_daemon()))?;
        let client = control
            .client_builder()
            .create()
            .map_err(|e| ClientError::Ipc(format!("cannot create a control client: {e:?}")))?;
        let wake = Wake::open(&node, machine);
        let mut c = Client {
            machine: machine.to_string(),
            node,
            _control: control,
            client,
            next_id: 1,
            wake,
        };
        c.status().map_err(|e| match e {
            ClientError::NoDaemon { .. } => explained(e),
            e => e,
        })?;
        Ok(c)
    }

    /// The machine this client talks to.
    pub fn machine(&self) -> &str {
        &self.machine
    }

    /// The node, for opening further ports.
    pub fn node(&self) -> &Node<ipc::Ipc> {
        &self.node
    }

    /// Sends `command` and waits for the answer (at most `REQUEST_TIMEOUT`). A refusal
    /// is returned as the response; only a missing answer is an error.
    pub fn request(&mut self, command: ControlCommand) -> Result<Response, ClientError> {
        self.request_within(command, REQUEST_TIMEOUT)
    }

    /// [`request`](Self::request) waiting at most `timeout`.
    pub fn request_within(
        &mut self,
        command: ControlCommand,
        timeout: Duration,
    ) -> Result<Response, ClientError> {
        let id = self.next_id;
        self.next_id += 1;
        let pending = self
            .client
            .send_copy(Request::from_command(command, id))
            .map_err(|_| ClientError::NoDaemon {
                machine: self.machine.clone(),
            })?;
        if let Some(wake) = &self.wake {
            let _ = wake.request.notify();
        }
        let deadline = Instant::now() + timeout;
        loop {
            match pending.receive() {
                Ok(Some(response)) if response.request_id == id => return Ok(*response),
                Ok(Some(_)) => {}
                Ok(None) => {}
                Err(_) => {
                    return Err(ClientError::NoDaemon {
                        machine: self.machine.clone(),
                    });
                }
            }
            let now = Instant::now();
            if now > deadline {
                return Err(ClientError::NoDaemon {
                    machine: self.machine.clone(),
                });
            }
            // An answer's notification ends the wait at once (a notification that came
            // before the wait began is kept, so none is missed); the poll stays as a
            // bound on how long a lost one could delay the answer.
            let wait = ANSWER_POLL.min(deadline - now);
            match &self.wake {
                Some(wake) if wake.answer.timed_wait(|_| {}, wait).is_ok() => {}
                _ => std::thread::sleep(wait),
            }
        }
    }

    /// The daemon's status.
    pub fn status(&mut self) -> Result<StatusMsg, ClientError> {
        Ok(self.request(ControlCommand::Status)?.status)
    }

    /// Sends a command; a refusal is an error with the daemon's words.
    pub fn command(&mut self, command: ControlCommand) -> Result<StatusMsg, ClientError> {
        let r = self.request(command)?;
        if r.reason == REASON_OK {
            Ok(r.status)
        } else {
            Err(ClientError::Refused(r.message().to_string()))
        }
    }
}

/// A reader of the setpoint stream that notices lost cycles and a stalled stream.
pub struct SetpointReader {
    machine: String,
    _service: ipc::SetpointsService,
    subscriber: iceoryx2::port::subscriber::Subscriber<ipc::Ipc, SetpointMsg, ()>,
    last_seq: Option<u64>,
    last_seen: Instant,
}

impl SetpointReader {
    /// Subscribes to the setpoints of `machine`.
    pub fn open(node: &Node<ipc::Ipc>, machine: &str) -> Result<SetpointReader, ClientError> {
        let service = ipc::open_setpoints(node, machine).map_err(|_| ClientError::NoDaemon {
            machine: machine.to_string(),
        })?;
        let subscriber = ipc::setpoint_subscriber(&service).map_err(ClientError::Service)?;
        Ok(SetpointReader {
            machine: machine.to_string(),
            _service: service,
            subscriber,
            last_seq: None,
            last_seen: Instant::now(),
        })
    }

    /// Takes every setpoint that has arrived, in order, calling `f` for each; an error if
    /// a cycle is missing between two of them (the reader fell behind) or, with
    /// `expect_stream`, if nothing arrived for [`STREAM_TIMEOUT`].
    pub fn drain(
        &mut self,
        expect_stream: bool,
        mut f: impl FnMut(&SetpointMsg) -> Result<(), ClientError>,
    ) -> Result<usize, ClientError> {
        let mut n = 0;
        loop {
            let msg = match self.subscriber.receive() {
                Ok(Some(sample)) => *sample,
                Ok(None) => break,
                Err(e) => return Err(ClientError::Ipc(format!("receiving setpoints: {e:?}"))),
            };
            if let Some(last) = self.last_seq
                && msg.seq != last + 1
            {
                return Err(ClientError::Gone {
                    machine: self.machine.clone(),
                    detail: format!(
                        "setpoints {} to {} were lost (the reader fell behind)",
                        last + 1,
                        msg.seq.saturating_sub(1)
                    ),
                });
            }
            self.last_seq = Some(msg.seq);
            n += 1;
            f(&msg)?;
        }
        let now = Instant::now();
        if n > 0 {
            self.last_seen = now;
        } else if expect_stream && now.duration_since(self.last_seen) > STREAM_TIMEOUT {
            return Err(ClientError::Gone {
                machine: self.machine.clone(),
                detail: format!(
                    "no setpoint for {} ms",
                    now.duration_since(self.last_seen).as_millis()
                ),
            });
        }
        Ok(n)
    }

    /// Restarts the stall timer (after a pause in reading that was not the daemon's).
    pub fn touch(&mut self) {
        self.last_seen = Instant::now();
    }
}

/// A publisher of one program's resolved moves.
pub struct MoveSender {
    _service: ipc::MovesService,
    publisher: iceoryx2::port::publisher::Publisher<ipc::Ipc, MoveMsg, ()>,
    /// Messages sent.
    pub sent: u64,
}

impl MoveSender {
    /// Opens the moves service of `machine`.
    pub fn open(node: &Node<ipc::Ipc>, machine: &str) -> Result<MoveSender, ClientError> {
        let service = ipc::open_moves(node, machine).map_err(|_| ClientError::NoDaemon {
            machine: machine.to_string(),
        })?;
        let publisher = ipc::move_publisher(&service).map_err(ClientError::Service)?;
        Ok(MoveSender {
            _service: service,
            publisher,
            sent: 0,
        })
    }

    /// Sends one message (the caller keeps within the flow-control window).
    pub fn send(&mut self, msg: MoveMsg) -> Result<(), ClientError> {
        self.publisher
            .send_copy(msg)
            .map_err(|e| ClientError::Ipc(format!("sending a move: {e:?}")))?;
        self.sent += 1;
        Ok(())
    }
}
