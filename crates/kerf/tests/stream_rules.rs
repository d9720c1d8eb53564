//! The moves stream as a contract (issue 25): the daemon enforces PROTOCOL.md's stream
//! rules against a client that breaks them, and its status tells the truth about every
//! program. Each test starts a daemon in this process (as `kerf run --embedded` does) on a
//! machine of its own, and talks to it through the same iceoryx2 services a foreign client
//! uses: raw `MoveMsg`s on the moves service, requests on the control service, setpoints
//! read from the setpoint service.

use std::f64::consts::PI;
use std::path::Path;
use std::time::{Duration, Instant};

use kerf::client::{Client, MoveSender, SetpointReader};
use kerf_config::Config;
use kerf_proto::{
    CORNER_EXACT_STOP, ControlCommand, KIND_ARC, KIND_LINE, MoveMsg, PROGRAM_END_ABORTED,
    PROGRAM_END_FINISHED, PROGRAM_END_NONE, PROGRAM_END_REFUSED, PROGRAM_FATE_ABORTED,
    PROGRAM_FATE_FINISHED, PROGRAM_FATE_REFUSED, PROGRAM_FATE_UNKNOWN, PROTOCOL_VERSION, Response,
    SetpointMsg, StatusMsg,
};

/// Upper bound on any wait.
const PATIENCE: Duration = Duration::from_secs(30);

struct Machine {
    _daemon: kerfd::Daemon,
    client: Client,
    sender: MoveSender,
    reader: SetpointReader,
    /// Every setpoint read so far.
    setpoints: Vec<SetpointMsg>,
}

impl Machine {
    fn start(tag: &str) -> Machine {
        let machine = format!("s{}_{tag}", std::process::id());
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join("kerf-stream-tests")
            .join(&machine);
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let text = kerf_testkit::config_text::without_homing(
            &std::fs::read_to_string(root.join("config/kerf.toml")).unwrap(),
        );
        let text = text.replacen(
            "machine = \"default\"",
            &format!("machine = \"{machine}\""),
            1,
        );
        let path = dir.join("kerf.toml");
        std::fs::write(&path, text).unwrap();
        let config = Config::load(&path).unwrap();
        let daemon = kerfd::start(&config, false).expect("daemon starts");
        let mut client = Client::connect(&machine).expect("daemon answers");
        let sender = MoveSender::open(client.node(), &machine).unwrap();
        let reader = SetpointReader::open(client.node(), &machine).unwrap();
        client.status().unwrap();
        let mut m = Machine {
            _daemon: daemon,
            client,
            sender,
            reader,
            setpoints: Vec::new(),
        };
        // Programs start once the drives are enabled.
        m.wait("the drives to be enabled", |s| {
            s.drives == kerf_proto::DRIVES_RUNNING
        });
        m
    }

    fn status(&mut self) -> StatusMsg {
        self.client.status().unwrap()
    }

    fn request(&mut self, c: ControlCommand) -> Response {
        self.client.request(c).unwrap()
    }

    fn fate(&mut self, program_id: u64) -> Response {
        self.request(ControlCommand::Program { program_id })
    }

    fn send(&mut self, msg: MoveMsg) {
        self.sender.send(msg).unwrap();
    }

    fn read(&mut self) {
        let out = &mut self.setpoints;
        self.reader
            .drain(false, |m| {
                out.push(*m);
                Ok(())
            })
            .unwrap();
    }

    fn wait(&mut self, what: &str, mut done: impl FnMut(&StatusMsg) -> bool) -> StatusMsg {
        let deadline = Instant::now() + PATIENCE;
        loop {
            self.read();
            let s = self.status();
            if done(&s) {
                return s;
            }
            assert!(Instant::now() < deadline, "waiting for {what}: {s:?}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Waits until the daemon has taken every message sent so far (some cycles pass).
    fn settle(&mut self) -> StatusMsg {
        let start = self.status().cycles;
        self.wait("cycles to pass", |s| s.cycles > start + 50)
    }

    fn position(&mut self) -> [f64; 6] {
        self.status().position_mm_deg
    }

    /// Setpoints of program `id` with a program cycle other than 0.
    fn moving_cycles(&mut self, id: u64) -> usize {
        self.read();
        self.setpoints
            .iter()
            .filter(|m| m.program_id == id && m.program_cycle != 0)
            .count()
    }
}

fn line(id: u64, seq: u64, from: [f64; 3], to: [f64; 3], feed_mm_min: f64) -> MoveMsg {
    let mut m = MoveMsg::zeroed();
    m.version = PROTOCOL_VERSION;
    m.kind = KIND_LINE;
    m.program_id = id;
    m.seq = seq;
    m.line = seq as u32;
    m.corner = CORNER_EXACT_STOP;
    m.feed_mm_min = feed_mm_min;
    m.start_mm = from;
    m.end_mm = to;
    m
}

fn xyz(p: &[f64; 6]) -> [f64; 3] {
    [p[0], p[1], p[2]]
}

/// A program of `n` lines out along X and back, from `p`, in 1 mm steps.
fn zigzag(id: u64, p: [f64; 3], n: u64) -> Vec<MoveMsg> {
    let mut out = Vec::new();
    let mut at = p;
    for k in 1..=n {
        let to = [p[0] + if k % 2 == 1 { 1.0 } else { 0.0 }, p[1], p[2]];
        out.push(line(id, k, at, to, 600.0));
        at = to;
    }
    out
}

#[test]
fn a_second_begin_while_a_program_is_open_is_refused_and_the_open_program_runs_on() {
    let mut m = Machine::start("second_begin");
    let p = m.position();
    let rejected0 = m.status().rejected;
    let (a, b) = (0xA1, 0xB2);
    m.send(MoveMsg::begin(a, p, 0));
    let moves = zigzag(a, xyz(&p), 4);
    m.send(moves[0]);
    m.send(moves[1]);
    // The intruder: a consistent BEGIN from the same position, its items and its END.
    m.send(MoveMsg::begin(b, p, 0));
    for msg in zigzag(b, xyz(&p), 2) {
        m.send(msg);
    }
    m.send(MoveMsg::end(b, 2));
    // The open program goes on to its END.
    m.send(moves[2]);
    m.send(moves[3]);
    m.send(MoveMsg::end(a, 4));
    let s = m.wait("program a to end", |s| {
        s.program_id == a && s.program_end != PROGRAM_END_NONE
    });
    assert_eq!(s.program_end, PROGRAM_END_FINISHED, "{}", s.fault_text());
    assert_eq!(s.program_done, 1);
    assert_eq!(
        s.rejected - rejected0,
        4,
        "the intruder's BEGIN, two items and END"
    );
    assert_eq!(s.moves_received, 4, "items only, BEGIN and END not counted");
    let fate_b = m.fate(b);
    assert_eq!(fate_b.program_fate, PROGRAM_FATE_REFUSED);
    assert!(
        fate_b.message().contains("still open"),
        "{}",
        fate_b.message()
    );
    assert_eq!(m.fate(a).program_fate, PROGRAM_FATE_FINISHED);
    assert_eq!(m.moving_cycles(b), 0, "the intruder never moved");
    // A BEGIN repeating a known id is refused, and does not move the machine.
    let p = m.position();
    m.send(MoveMsg::begin(a, p, 0));
    for msg in zigzag(a, xyz(&p), 2) {
        m.send(msg);
    }
    m.send(MoveMsg::end(a, 2));
    let s = m.settle();
    assert_eq!(
        s.rejected - rejected0,
        8,
        "the repeat's BEGIN, items and END"
    );
    assert_eq!(s.position_mm_deg, p);
    assert_eq!(m.fate(a).program_fate, PROGRAM_FATE_FINISHED);
}

#[test]
fn a_begin_away_from_the_machine_or_not_a_number_is_refused_counted_and_never_moves() {
    let mut m = Machine::start("wrong_start");
    let p = m.position();
    let rejected0 = m.status().rejected;
    let id = 0x51;
    let mut away = p;
    away[0] += 0.01;
    m.send(MoveMsg::begin(id, away, 0));
    for msg in zigzag(id, xyz(&away), 2) {
        m.send(msg);
    }
    m.send(MoveMsg::end(id, 2));
    let s = m.wait("the program to be refused", |s| {
        s.program_id == id && s.program_end != PROGRAM_END_NONE
    });
    assert_eq!(s.program_end, PROGRAM_END_REFUSED);
    assert_eq!(s.program_done, 0);
    assert_eq!(s.rejected - rejected0, 1, "the BEGIN");
    assert!(s.fault_text().contains("starts at X"), "{}", s.fault_text());
    assert_eq!(m.fate(id).program_fate, PROGRAM_FATE_REFUSED);
    assert_eq!(m.moving_cycles(id), 0);
    assert_eq!(m.position(), p);

    // NaN in BEGIN's start: refused as a message, before anything.
    let nan = 0x52;
    let mut start = p;
    start[1] = f64::NAN;
    m.send(MoveMsg::begin(nan, start, 0));
    m.send(MoveMsg::end(nan, 0));
    let s = m.settle();
    assert_eq!(s.rejected - rejected0, 3, "the NaN BEGIN and its END");
    let f = m.fate(nan);
    assert_eq!(f.program_fate, PROGRAM_FATE_REFUSED);
    assert!(f.message().contains("start_mm"), "{}", f.message());
    assert_eq!(m.moving_cycles(nan), 0);
    assert_eq!(m.position(), p);
    assert_eq!(m.fate(0x53).program_fate, PROGRAM_FATE_UNKNOWN);
}

#[test]
fn a_program_refused_at_its_first_move_publishes_no_moving_setpoint() {
    let mut m = Machine::start("refused_first");
    let p = m.position();
    let id = 0x61;
    m.send(MoveMsg::begin(id, p, 0));
    // Far outside the travel (X to 5000 mm on a machine of ±1000 mm).
    let mut far = xyz(&p);
    far[0] = 5000.0;
    m.send(line(id, 1, xyz(&p), far, 600.0));
    m.send(MoveMsg::end(id, 1));
    let s = m.wait("the program to be refused", |s| {
        s.program_id == id && s.program_end != PROGRAM_END_NONE
    });
    assert_eq!(s.program_end, PROGRAM_END_REFUSED, "{}", s.fault_text());
    assert!(s.fault_text().contains("travel"), "{}", s.fault_text());
    m.settle();
    assert_eq!(m.moving_cycles(id), 0);
    assert_eq!(m.position(), p);
}

#[test]
fn an_inconsistent_arc_is_refused_in_millimetres_and_nothing_moves() {
    let mut m = Machine::start("bad_arc");
    let p = m.position();
    for (k, radius_mm) in [1e8, 1e10].into_iter().enumerate() {
        let id = 0x71 + k as u64;
        let rejected0 = m.status().rejected;
        let start = xyz(&p);
        // The centre straight below the start; the end 10 mm along the circle.
        let center = [start[0], start[1] - radius_mm, start[2]];
        let angle = 10.0 / radius_mm;
        let end = [
            center[0] - radius_mm * angle.sin(),
            center[1] + radius_mm * angle.cos(),
            start[2],
        ];
        let mut arc = line(id, 1, start, end, 12000.0);
        arc.kind = KIND_ARC;
        arc.center_mm = center;
        arc.axis = [0.0, 0.0, 1.0];
        arc.sweep_rad = angle + 9e-7;
        m.send(MoveMsg::begin(id, p, 0));
        m.send(arc);
        m.send(MoveMsg::end(id, 1));
        let s = m.wait("the program to be refused", |s| {
            s.program_id == id && s.program_end != PROGRAM_END_NONE
        });
        assert_eq!(s.program_end, PROGRAM_END_REFUSED);
        assert_eq!(s.rejected - rejected0, 1, "the arc");
        let f = m.fate(id);
        assert_eq!(f.program_fate, PROGRAM_FATE_REFUSED);
        // The disagreement, about 9e-7 × radius, named in mm.
        let expected_mm = 9e-7 * radius_mm;
        let text = f.message().to_string();
        assert!(
            text.contains(&format!("{:.0}", expected_mm)) || text.contains("mm"),
            "{text}"
        );
        assert_eq!(m.moving_cycles(id), 0);
        assert_eq!(m.position(), p);
    }
}

#[test]
fn override_zero_is_reported_in_the_answer_and_the_status() {
    let mut m = Machine::start("override_zero");
    let r = m.request(ControlCommand::Override { percent: 0.0 });
    assert_eq!(r.reason, kerf_proto::REASON_OK);
    assert_eq!(r.status.override_pct, 0.0, "the answer is the state after");
    assert_eq!(m.status().override_pct, 0.0);
    let r = m.request(ControlCommand::Override { percent: 37.5 });
    assert_eq!(r.status.override_pct, 37.5);
}

#[test]
fn an_abort_ends_a_program_that_is_still_being_sent_for_everyone() {
    let mut m = Machine::start("abort_streaming");
    let p = m.position();
    let id = 0x81;
    let window = m.status().window_items;
    m.send(MoveMsg::begin(id, p, 0));
    let moves = zigzag(id, xyz(&p), 4 * window);
    // More than the lookahead queue holds, so the motion starts before END; sent with
    // the flow control of PROTOCOL.md.
    let mut sent = 0u64;
    let mut next = moves.iter();
    let send_window = |m: &mut Machine, sent: &mut u64, upto: u64| {
        while *sent < upto {
            let Some(msg) = next.next() else { break };
            m.send(*msg);
            *sent += 1;
        }
    };
    let mut send_window = send_window;
    let deadline = Instant::now() + PATIENCE;
    loop {
        let s = m.status();
        if s.program_id == id && s.line > 0 {
            break;
        }
        let acked = if s.program_id == id {
            s.moves_received
        } else {
            0
        };
        send_window(&mut m, &mut sent, acked + window);
        assert!(Instant::now() < deadline, "the motion never started: {s:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
    let r = m.request(ControlCommand::Abort);
    assert_eq!(r.reason, kerf_proto::REASON_OK);
    // The client goes on sending (as a client that has not looked yet would).
    let received = m.status().moves_received;
    send_window(&mut m, &mut sent, received + window);
    let s = m.wait("the program to end", |s| {
        s.program_id == id && s.program_end != PROGRAM_END_NONE
    });
    assert_eq!(s.program_end, PROGRAM_END_ABORTED);
    assert_eq!(s.program_done, 0);
    assert_eq!(m.fate(id).program_fate, PROGRAM_FATE_ABORTED);
    let at = s.position_mm_deg;
    let received = m.status().moves_received;
    send_window(&mut m, &mut sent, received + window);
    m.send(MoveMsg::end(id, sent));
    let s = m.settle();
    assert_eq!(
        s.position_mm_deg, at,
        "nothing of the aborted program moves"
    );
    assert_eq!(s.program_id, id);
    assert_eq!(s.program_end, PROGRAM_END_ABORTED);
    // A new program is accepted at once and runs.
    let next_id = 0x82;
    let p = s.position_mm_deg;
    m.send(MoveMsg::begin(next_id, p, 0));
    for msg in zigzag(next_id, xyz(&p), 2) {
        m.send(msg);
    }
    m.send(MoveMsg::end(next_id, 2));
    let s = m.wait("the next program to end", |s| {
        s.program_id == next_id && s.program_end != PROGRAM_END_NONE
    });
    assert_eq!(s.program_end, PROGRAM_END_FINISHED, "{}", s.fault_text());
    assert_eq!(m.fate(id).program_fate, PROGRAM_FATE_ABORTED);
}

#[test]
fn consistent_extreme_arcs_run_without_a_safety_trip() {
    let mut m = Machine::start("extreme_arcs");
    for (k, radius_mm) in [1e-3, 1.0, 1e4, 1e8, 1e12].into_iter().enumerate() {
        let p = m.position();
        let id = 0x91 + k as u64;
        let start = xyz(&p);
        let center = [start[0], start[1] - radius_mm, start[2]];
        // Two turns on the small radii, 5 mm of path on the large ones.
        let sweep = if radius_mm < 10.0 {
            4.0 * PI
        } else {
            5.0 / radius_mm
        };
        let end = [
            center[0] - radius_mm * sweep.sin(),
            center[1] + radius_mm * sweep.cos(),
            start[2] - 0.5,
        ];
        let mut arc = line(id, 1, start, end, 3000.0);
        arc.kind = KIND_ARC;
        arc.center_mm = center;
        arc.axis = [0.0, 0.0, 1.0];
        arc.sweep_rad = sweep;
        m.send(MoveMsg::begin(id, p, 0));
        m.send(arc);
        m.send(MoveMsg::end(id, 1));
        let s = m.wait("the arc to end", |s| {
            s.program_id == id && s.program_end != PROGRAM_END_NONE
        });
        assert_eq!(
            s.program_end,
            PROGRAM_END_FINISHED,
            "radius {radius_mm}: {}",
            s.fault_text()
        );
        assert_eq!(s.safety_check, kerf_proto::SAFETY_NONE);
        let at = xyz(&s.position_mm_deg);
        assert_eq!(at, arc.end_mm, "radius {radius_mm}: ends at end_mm");
    }
}

/// The control wake-ups are optional for a foreign client (PROTOCOL.md): one that sends a
/// request on the control service without notifying `control-request`, and polls for
/// the answer, is answered; the daemon notifies `control-answer` after the answer; and a
/// client that notifies `control-request` is answered too.
#[test]
fn a_client_that_never_notifies_is_answered_and_the_daemon_notifies_each_answer() {
    use iceoryx2::prelude::*;
    let m = Machine::start("wake");
    let machine = m.client.machine().to_string();
    let node = NodeBuilder::new()
        .create::<ipc::Service>()
        .expect("a node of the foreign client");
    let name = |which: &str| {
        ServiceName::new(&kerf_proto::service_name(&machine, which).unwrap()).unwrap()
    };
    let control = node
        .service_builder(&name(kerf_proto::SERVICE_CONTROL))
        .request_response::<kerf_proto::Request, Response>()
        .open()
        .expect("the control service");
    let client = control.client_builder().create().unwrap();
    let answers = node
        .service_builder(&name(kerf_proto::SERVICE_CONTROL_ANSWER))
        .event()
        .open()
        .expect("the daemon creates the answer event service");
    let answered = answers.listener_builder().create().unwrap();
    let requests = node
        .service_builder(&name(kerf_proto::SERVICE_CONTROL_REQUEST))
        .event()
        .open()
        .expect("the daemon creates the request event service");
    let wake = requests.notifier_builder().create().unwrap();
    // Notifications of answers to other clients (the Machine's own) are gone first.
    answered.try_wait(|_| {}).unwrap();

    for (id, notify) in [(901u64, false), (902, true)] {
        let request = kerf_proto::Request::from_command(ControlCommand::Status, id);
        let pending = client.send_copy(request).unwrap();
        if notify {
            wake.notify().unwrap();
        }
        let deadline = Instant::now() + PATIENCE;
        let response = loop {
            if let Some(r) = pending.receive().unwrap() {
                break *r;
            }
            assert!(Instant::now() < deadline, "request {id} was never answered");
            std::thread::sleep(Duration::from_millis(1));
        };
        assert_eq!(response.request_id, id);
        assert_eq!(response.reason, kerf_proto::REASON_OK);
        // The notification follows the answer: wait for it (bounded).
        let mut notified = 0;
        let deadline = Instant::now() + PATIENCE;
        while notified == 0 && Instant::now() < deadline {
            notified += answered.timed_wait(|_| {}, PATIENCE).unwrap();
        }
        assert!(notified > 0, "no answer notification after request {id}");
    }
}
