//! `kerf jog` and `kerf home`: moving the machine by hand through its daemon.

use std::io::{self, Write};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use clap::Args;
use kerf::client::Client;
use kerf_proto::{ControlCommand, Jog, StatusMsg};

use crate::Failure;
use crate::machine::{MachineArgs, client_failure, connect, refused, stop_flag};

/// How often a command that waits polls the daemon's status.
const POLL: Duration = Duration::from_millis(20);

#[derive(Args)]
pub struct JogArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// The axis and, for a continuous jog, its direction: `X+`, `Z-`, `a+`; `X` alone with
    /// `--step` or `--to`.
    #[arg(value_name = "AXIS[+|-]", allow_hyphen_values = true)]
    pub axis: String,
    /// Speed, mm/s (deg/s on A, B, C); default: `[jog] default_speed_pct` of the axis's
    /// velocity (capped at `[homing] unhomed_jog_pct` until the axis is homed).
    #[arg(long, value_name = "MM_S")]
    pub speed: Option<f64>,
    /// Move by this distance and stop there exactly (the sign of `X+`/`X-` applies, else
    /// the step's own).
    #[arg(
        long,
        value_name = "MM",
        allow_hyphen_values = true,
        conflicts_with = "to"
    )]
    pub step: Option<f64>,
    /// Move to this machine coordinate and stop there exactly.
    #[arg(long, value_name = "MM", allow_hyphen_values = true)]
    pub to: Option<f64>,
    /// A continuous jog: stop after this many seconds (else it moves until Ctrl-C or
    /// SIGTERM).
    #[arg(long = "for", value_name = "SECONDS", conflicts_with_all = ["step", "to"])]
    pub duration_s: Option<f64>,
}

#[derive(Args)]
pub struct HomeArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// The axes to home (`X`, `Z Y`, `XYZ`), in their configured home sequence.
    #[arg(value_name = "AXIS", required_unless_present = "all")]
    pub axes: Vec<String>,
    /// Every axis of the machine.
    #[arg(long, conflicts_with = "axes")]
    pub all: bool,
}

/// The axis index of a letter.
fn axis_index(c: char) -> Option<usize> {
    kerf_geom::AXIS_NAMES
        .iter()
        .position(|a| a.eq_ignore_ascii_case(&c))
}

/// The latched fault or the refusal in the status, in words.
fn fault_words(s: &StatusMsg) -> String {
    kerfd::fault_text::safety_text(s).unwrap_or_else(|| s.fault_text().to_string())
}

/// `kerf jog`.
pub fn jog(args: &JogArgs) -> Result<(), Failure> {
    let mut chars = args.axis.chars();
    let (Some(letter), sign) = (chars.next(), chars.as_str()) else {
        return Err(Failure::Error(
            "kerf: error: jog: name an axis, e.g. X+".into(),
        ));
    };
    let axis = axis_index(letter).ok_or_else(|| {
        Failure::Error(format!(
            "kerf: error: jog: unknown axis `{letter}` (X, Y, Z, A, B or C)"
        ))
    })?;
    let direction = match sign {
        "+" => Some(true),
        "-" => Some(false),
        "" => None,
        other => {
            return Err(Failure::Error(format!(
                "kerf: error: jog: `{}{other}`: the direction is + or -",
                letter
            )));
        }
    };
    let speed = args.speed.unwrap_or(0.0);
    if !(speed.is_finite() && speed >= 0.0) || args.speed == Some(0.0) {
        return Err(Failure::Error(format!(
            "kerf: error: jog: the speed must be positive, got {speed}"
        )));
    }
    let jog = match (args.step, args.to, direction) {
        (Some(d), _, dir) => {
            if !(d.is_finite() && d != 0.0) {
                return Err(Failure::Error(format!(
                    "kerf: error: jog: the step must be a distance other than 0, got {d}"
                )));
            }
            Jog::Step(match dir {
                Some(true) => d.abs(),
                Some(false) => -d.abs(),
                None => d,
            })
        }
        (None, Some(x), None) => {
            if !x.is_finite() {
                return Err(Failure::Error(format!(
                    "kerf: error: jog: the target {x} is not a number"
                )));
            }
            Jog::To(x)
        }
        (None, Some(_), Some(_)) => {
            return Err(Failure::Error(
                "kerf: error: jog: --to takes the axis without a direction (`X --to 12.5`)".into(),
            ));
        }
        (None, None, Some(positive)) => Jog::Continuous(positive),
        (None, None, None) => {
            return Err(Failure::Error(format!(
                "kerf: error: jog: `{letter}` needs a direction (`{letter}+`, `{letter}-`), --step or --to"
            )));
        }
    };
    let (mut client, config) = connect(&args.machine)?;
    let stop = stop_flag()?;
    let command = ControlCommand::Jog {
        axis: axis as u8,
        jog,
        speed,
    };
    client.command(command).map_err(refused)?;
    let bit = 1u32 << axis;
    if let Jog::Continuous(_) = jog {
        // The daemon's dead man's switch: renewed well within its time.
        let renew = Duration::from_millis(u64::from(config.jog.deadman_ms / 4).max(5));
        let until = args
            .duration_s
            .map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
        let mut next = Instant::now() + renew;
        while !stop.load(Ordering::Acquire) && until.is_none_or(|u| Instant::now() < u) {
            std::thread::sleep(next.saturating_duration_since(Instant::now()).min(POLL));
            if Instant::now() >= next {
                let s = client.command(command).map_err(refused)?;
                if s.jogging & bit == 0 {
                    // It stopped on its own: at a soft limit, or a fault.
                    break;
                }
                next += renew;
            }
        }
        client
            .command(ControlCommand::JogStop { axis: axis as u8 })
            .map_err(refused)?;
    }
    let s = wait_until(&mut client, &stop, axis as u8, |s| s.jogging & bit == 0)?;
    if s.fault != 0 || s.state == kerf_proto::STATE_FAULT {
        return Err(Failure::Error(format!(
            "kerf: error: the jog stopped on a fault: {}",
            fault_words(&s)
        )));
    }
    let unit = if axis >= 3 { "deg" } else { "mm" };
    writeln!(
        io::stdout().lock(),
        "{} {:.4} {unit}",
        kerf_geom::AXIS_NAMES[axis],
        s.position_mm_deg[axis]
    )?;
    Ok(())
}

/// Polls the status until `done` says so (a Ctrl-C stops the jog of `axis` and goes on
/// waiting for its stop); returns the last status.
fn wait_until(
    client: &mut Client,
    stop: &std::sync::atomic::AtomicBool,
    axis: u8,
    done: impl Fn(&StatusMsg) -> bool,
) -> Result<StatusMsg, Failure> {
    let mut stopped = false;
    loop {
        let s = client.status().map_err(client_failure)?;
        if done(&s) {
            return Ok(s);
        }
        if stop.load(Ordering::Acquire) && !stopped {
            stopped = true;
            client
                .command(ControlCommand::JogStop { axis })
                .map_err(refused)?;
        }
        std::thread::sleep(POLL);
    }
}

/// The homing phase's name.
fn phase_name(phase: u8) -> &'static str {
    match phase {
        kerf_proto::HOME_PHASE_WAITING => "waiting for the axes homed before it",
        kerf_proto::HOME_PHASE_MOVE_OFF => "moving off the home switch",
        kerf_proto::HOME_PHASE_SEARCH => "searching for the home switch",
        kerf_proto::HOME_PHASE_BACK_OFF => "backing off the home switch",
        kerf_proto::HOME_PHASE_LATCH => "latching the home switch",
        kerf_proto::HOME_PHASE_FINAL => "moving to the home position",
        _ => "idle",
    }
}

/// `kerf home`.
pub fn home(args: &HomeArgs) -> Result<(), Failure> {
    let (mut client, _config) = connect(&args.machine)?;
    let status = client.status().map_err(client_failure)?;
    let mut mask = 0u32;
    if args.all {
        mask = status.axes_mask & 0b11_1111;
    } else {
        for word in &args.axes {
            for c in word.chars().filter(|c| !c.is_whitespace() && *c != ',') {
                let i = axis_index(c).ok_or_else(|| {
                    Failure::Error(format!(
                        "kerf: error: home: unknown axis `{c}` (X, Y, Z, A, B or C)"
                    ))
                })?;
                mask |= 1 << i;
            }
        }
    }
    if mask == 0 {
        return Err(Failure::Error("kerf: error: home: no axis to home".into()));
    }
    let stop = stop_flag()?;
    home_axes(&mut client, mask, &stop)
}

/// Homes the axes of `mask` and waits until they are homed, telling the progress on
/// standard error; a Ctrl-C (`stop`) aborts.
pub(crate) fn home_axes(
    client: &mut Client,
    mask: u32,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<(), Failure> {
    // A daemon just started enables its drives first (a few cycles).
    let enabling = Instant::now();
    while client.status().map_err(client_failure)?.drives == kerf_proto::DRIVES_ENABLING
        && enabling.elapsed() < Duration::from_secs(10)
    {
        std::thread::sleep(POLL);
    }
    client
        .command(ControlCommand::Home { axes: mask })
        .map_err(refused)?;
    let mut phases = [u8::MAX; 6];
    let mut err = io::stderr().lock();
    loop {
        let s = client.status().map_err(client_failure)?;
        for (i, p) in phases.iter_mut().enumerate() {
            let now = s.home_phase[i];
            if mask & (1 << i) != 0 && now != *p {
                if now != kerf_proto::HOME_PHASE_IDLE {
                    let _ = writeln!(
                        err,
                        "kerf: homing {}: {}",
                        kerf_geom::AXIS_NAMES[i],
                        phase_name(now)
                    );
                }
                *p = now;
            }
        }
        if s.fault != 0 || s.safety_check != 0 {
            return Err(Failure::Error(format!(
                "kerf: error: homing stopped: {}",
                fault_words(&s)
            )));
        }
        if s.homing & mask == 0 {
            let missing = (0..6).find(|i| mask & (1 << i) != 0 && s.homed & (1 << i) == 0);
            if let Some(i) = missing {
                return Err(Failure::Error(format!(
                    "kerf: error: axis {} was not homed (homing was aborted)",
                    kerf_geom::AXIS_NAMES[i]
                )));
            }
            let names: String = (0..6)
                .filter(|i| mask & (1 << i) != 0)
                .map(|i| kerf_geom::AXIS_NAMES[i])
                .collect();
            let _ = writeln!(err, "kerf: homed {names}");
            return Ok(());
        }
        if stop.load(Ordering::Acquire) {
            let _ = client.command(ControlCommand::Abort);
            return Err(Failure::Exit(1, "kerf: homing aborted".into()));
        }
        std::thread::sleep(POLL);
    }
}
