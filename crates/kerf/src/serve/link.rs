//! The link to the daemon: one thread that owns the iceoryx2 client (its ports stay on
//! the thread that made them), asks the daemon for its status every
//! [`STATUS_PERIOD`], publishes it as the API's status message to every web client
//! through a watch channel (the latest only: a slow client skips, never queues), and
//! carries the control requests of the web clients to the daemon one at a time.
//!
//! Without a daemon it says so in the status message (`"connected": false` with the
//! reason) and tries again every [`RECONNECT_PERIOD`]; a control request is refused
//! meanwhile.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use kerf_config::Config;
use kerf_proto::{ControlCommand, REASON_OK};
use tokio::sync::watch;

use crate::client::Client;
use crate::dro::Dro;
use crate::status_view::{status_json, subdevice_names};

/// How often the status is asked for and published: 20 Hz.
pub const STATUS_PERIOD: Duration = Duration::from_millis(50);

/// How often a missing daemon is looked for.
pub const RECONNECT_PERIOD: Duration = Duration::from_millis(500);

/// Where the answer to an [`Ask`] goes: the status after it (the API's status object), or
/// why it was refused.
pub type Answer = Box<dyn FnOnce(Result<String, Refused>) + Send>;

/// A control request of a web or OPC UA client, with where the answer goes.
pub struct Ask {
    /// What to ask the daemon.
    pub command: ControlCommand,
    /// Called with the answer.
    pub answer: Answer,
}

/// Why a control request did not reach or was refused by the daemon.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refused {
    /// The daemon refused it, in its words.
    Daemon(String),
    /// No daemon answers.
    NoDaemon(String),
}

/// One status message of the API: `{"api":1,"seq":N,"t_ms":T,"connected":…,…}`. `seq`
/// counts the messages published, `t_ms` is the link's clock (ms since it started) when
/// the status was read.
fn message(seq: u64, t_ms: u64, body: &str) -> String {
    format!(
        "{{\"api\":{},\"seq\":{seq},\"t_ms\":{t_ms},{body}}}",
        super::API_VERSION
    )
}

/// The machine's settings (its parameter file and tool table read) for the DRO, read
/// again only when one of the two files changed, not at every status.
#[derive(Default)]
struct MachineFiles {
    /// The files' identity when last read: inode, size, modification time.
    stamp: Option<[(u64, u64, i64, i64); 2]>,
    /// The settings read then (None: they could not be read).
    settings: Option<kerf_gcode::Settings>,
}

impl MachineFiles {
    /// The DRO at `s`; None when the machine's files cannot be read (left out, as `kerf
    /// status` does).
    fn dro(&mut self, config: &Config, s: &kerf_proto::StatusMsg) -> Option<Dro> {
        use std::os::unix::fs::MetadataExt;
        let stamp_of = |p: std::path::PathBuf| {
            std::fs::metadata(p).map_or((0, 0, 0, 0), |m| {
                (m.ino(), m.size(), m.mtime(), m.mtime_nsec())
            })
        };
        let stamp = [
            stamp_of(config.machine_parameter_file()),
            stamp_of(config.machine_tool_table()),
        ];
        if self.stamp != Some(stamp) {
            self.stamp = Some(stamp);
            self.settings = config.machine_settings().ok();
        }
        let settings = self.settings.clone()?;
        Some(Dro::with_settings(
            config,
            settings,
            s.position_mm_deg,
            s.tool_in_spindle,
        ))
    }
}

/// The status object of the daemon's status `s` (`kerf status --json`'s).
fn status_object(
    config: &Config,
    names: &[String],
    files: &mut MachineFiles,
    s: &kerf_proto::StatusMsg,
) -> String {
    let dro = files.dro(config, s);
    status_json(&config.machine, names, s, dro.as_ref())
}

/// Runs the link until every sender of `asks` is gone and `status` has no receiver.
pub fn run(config: Config, status: watch::Sender<Arc<String>>, asks: Receiver<Ask>) {
    let names = subdevice_names(&config);
    let mut files = MachineFiles::default();
    let started = Instant::now();
    let mut seq = 0u64;
    let mut client: Option<Client> = None;
    let mut next_try = Instant::now();
    let mut next_status = Instant::now();
    let mut absent = String::new();
    loop {
        let now = Instant::now();
        if client.is_none() && now >= next_try {
            match Client::connect(&config.machine) {
                Ok(c) => client = Some(c),
                Err(e) => absent = e.to_string(),
            }
            next_try = now + RECONNECT_PERIOD;
        }
        if now >= next_status {
            next_status = now + STATUS_PERIOD;
            let t_ms = started.elapsed().as_millis() as u64;
            let body = match client.as_mut().map(Client::status) {
                Some(Ok(s)) => format!(
                    "\"connected\":true,\"status\":{}",
                    status_object(&config, &names, &mut files, &s)
                ),
                Some(Err(e)) => {
                    client = None;
                    absent = e.to_string();
                    format!("\"connected\":false,\"reason\":{}", json_string(&absent))
                }
                None => format!("\"connected\":false,\"reason\":{}", json_string(&absent)),
            };
            seq += 1;
            // Kept for the next web client even while none is connected.
            status.send_replace(Arc::new(message(seq, t_ms, &body)));
        }
        let wait = next_status.saturating_duration_since(Instant::now());
        match asks.recv_timeout(wait) {
            Ok(ask) => {
                let answer = match client.as_mut() {
                    None => Err(Refused::NoDaemon(absent.clone())),
                    Some(c) => {
                        // A reset may take as long as the daemon's reset does (a bus
                        // brought back to OP); everything else answers at once.
                        let patience = match ask.command {
                            ControlCommand::Reset => kerfd::reset_patience(&config),
                            _ => crate::client::REQUEST_TIMEOUT,
                        };
                        match c.request_within(ask.command, patience) {
                            Ok(r) if r.reason == REASON_OK => {
                                Ok(status_object(&config, &names, &mut files, &r.status))
                            }
                            Ok(r) => Err(Refused::Daemon(r.message().to_string())),
                            Err(e) => {
                                client = None;
                                absent = e.to_string();
                                Err(Refused::NoDaemon(absent.clone()))
                            }
                        }
                    }
                };
                (ask.answer)(answer);
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
    }
}

/// `text` as a JSON string.
pub fn json_string(text: &str) -> String {
    serde_json::Value::String(text.to_owned()).to_string()
}
