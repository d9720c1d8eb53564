//! A private network namespace with a veth pair, for the tests that put an EtherCAT
//! network (the emulator `kerf-ecat-sim`) on one end and Kerf on the other. The tests run
//! as root (CI does); where a namespace cannot be made, [`Netns::new`] panics saying
//! why, so a test fails instead of passing without having run.
//!
//! Everything is removed on drop, even after a failed assertion: the processes still in
//! the namespace are killed, then the namespace (and the veth pair in it) is deleted.

use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

/// The MainDevice's end of the veth pair.
pub const MAIN_IF: &str = "ecatA";
/// The network's (the emulator's) end.
pub const NETWORK_IF: &str = "ecatB";

static COUNTER: AtomicU32 = AtomicU32::new(0);

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("cannot run `ip {}`: {e}", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "`ip {}` failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// A network namespace holding a veth pair [`MAIN_IF`] — [`NETWORK_IF`], both up.
#[derive(Debug)]
pub struct Netns {
    name: String,
}

impl Netns {
    /// Makes the namespace `PREFIX-PID-N`; panics with the reason where it cannot (these
    /// tests need root and iproute2: they fail rather than pass without running).
    pub fn new(prefix: &str) -> Netns {
        let name = format!(
            "{prefix}-{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::SeqCst)
        );
        if let Err(e) = ip(&["netns", "add", &name]) {
            panic!(
                "cannot create a network namespace (the EtherCAT tests need root and iproute2): {e}"
            );
        }
        let ns = Netns { name };
        let n = ns.name.as_str();
        for args in [
            &[
                "-n", n, "link", "add", MAIN_IF, "type", "veth", "peer", "name", NETWORK_IF,
            ][..],
            &["-n", n, "link", "set", MAIN_IF, "up"],
            &["-n", n, "link", "set", NETWORK_IF, "up"],
        ] {
            if let Err(e) = ip(args) {
                panic!("cannot set up the veth pair: {e}");
            }
        }
        ns
    }

    /// The namespace's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// A command that runs `program` inside the namespace (`ip netns exec`, which execs
    /// it: the child's process id is the program's).
    pub fn command(&self, program: &str) -> Command {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", &self.name, program]);
        c
    }
}

impl Drop for Netns {
    fn drop(&mut self) {
        // Whatever still runs inside (an emulator, a daemon) is killed first.
        if let Ok(out) = Command::new("ip")
            .args(["netns", "pids", &self.name])
            .output()
        {
            for pid in String::from_utf8_lossy(&out.stdout).split_whitespace() {
                let _ = Command::new("kill").args(["-KILL", pid]).status();
            }
        }
        let _ = ip(&["netns", "delete", &self.name]);
    }
}
