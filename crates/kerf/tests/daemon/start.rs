//! Starting the daemon: what is refused before anything moves, what a killed start leaves
//! behind, and where its threads run.

use super::*;

#[test]
fn a_period_outside_the_daemons_range_is_refused_before_anything_starts() {
    for period in ["50", "100", "20000"] {
        let env = Env::new(
            &format!("period{period}"),
            &[("period_us = 1000", &format!("period_us = {period}"))],
        );
        let out = Command::new(kerfd())
            .args(["--config", env.config_arg()])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "period {period}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("period_us") && err.contains("125 to 10000"),
            "period {period}: {err}"
        );
        // Nothing was created: no daemon answers for the machine.
        assert_eq!(env.kerf("status", &[]).status.code(), Some(1));
    }
}

#[test]
fn an_ethercat_bus_that_cannot_be_opened_is_refused_at_start() {
    // The example bus on `eth1`, which this machine does not have (or which is no EtherCAT
    // bus): the daemon names the interface and exits before serving anything.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let example = root.join("config/ethercat-example.toml");
    let out = Command::new(kerfd())
        .args(["--config", example.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("EtherCAT interface eth1"), "{err}");
}

#[test]
fn a_configuration_that_does_not_load_is_named() {
    let out = Command::new(kerfd())
        .args(["--config", "/nonexistent/kerf.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/kerf.toml"), "{err}");
}

#[test]
fn a_second_daemon_or_an_embedded_run_for_the_same_machine_is_refused() {
    let env = Env::new("twice", &[]);
    let _first = env.start_daemon("kerfd");
    let out = Command::new(kerfd())
        .args(["--config", env.config_arg()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("already running") && err.contains(&env.machine),
        "{err}"
    );
    let program = env.write("part.ngc", PART);
    let out = env.kerf("run", &["--embedded", program.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("already running"), "{err}");
    // The first one still serves.
    assert!(env.kerf("status", &[]).status.success());
}

#[test]
fn a_daemon_killed_while_it_starts_leaves_nothing_that_stops_the_next() {
    let env = Env::new("startkill", &[]);
    // SIGKILL at staggered moments of the start-up: some before, some while, some after
    // the services are created.
    for i in 0..24u64 {
        let mut d = spawn(
            "kerfd-killed",
            &env.dir,
            kerfd(),
            &["--config", env.config_arg()],
        );
        std::thread::sleep(Duration::from_millis(2 + 4 * i));
        d.signal("KILL");
        wait(&mut d, 1);
    }
    // Files a killed creator left count as abandoned after 100 ms.
    std::thread::sleep(kerfd::ipc::UNFINISHED_AFTER * 2);
    let _daemon = env.start_daemon("kerfd");
    let program = env.write("short.ngc", "G21 G90\nG1 X2 Y1 F3000\nG0 X0 Y0\nM2\n");
    env.run_ok("run", &program, None);
}

#[test]
fn a_service_segment_left_empty_by_a_killed_creator_stops_nothing() {
    // A process killed between creating a service's shared-memory segment and sizing it
    // leaves the segment empty and write-only. iceoryx2 waits without end when it opens
    // one, and every process that creates a node opens the segments of dead nodes'
    // services to clean up after them: every later `kerf` command hung (a daemon test
    // that kills starting daemons left one, and another test's `kerf status` hung in CI).
    // Made here on purpose: a serving daemon's control service's dynamic segment emptied
    // as a killed creator leaves it, and the daemon killed.
    use iceoryx2::prelude::SemanticString as _;
    use std::os::unix::fs::PermissionsExt;
    let env = Env::new("emptyseg", &[]);
    let mut daemon = env.start_daemon("kerfd");
    // The segment is named after the service's unique id (`unique_value · 2⁶⁴ +
    // payload_value`), which its static file records.
    let services = iceoryx2::prelude::Config::global_config()
        .global
        .service_dir();
    let services = PathBuf::from(String::from_utf8_lossy(services.as_bytes()).into_owned());
    let wanted = format!("service_name = \"kerf/{}/control\"", env.machine);
    let id = fs::read_dir(&services)
        .unwrap()
        .flatten()
        .find_map(|e| {
            let text = fs::read_to_string(e.path()).ok()?;
            text.lines().any(|l| l == wanted).then_some(())?;
            let value = |key: &str| -> Option<u128> {
                let line = text.lines().find(|l| l.starts_with(key))?;
                line.split('=').nth(1)?.trim().parse().ok()
            };
            Some((value("unique_value")? << 64) + value("payload_value")?)
        })
        .expect("the control service's static file");
    let segment = fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            name.starts_with("iox2_") && name.ends_with(&format!("_{id}.dynamic"))
        })
        .expect("the control service's dynamic segment");
    fs::OpenOptions::new()
        .write(true)
        .open(&segment)
        .unwrap()
        .set_len(0)
        .unwrap();
    fs::set_permissions(&segment, fs::Permissions::from_mode(0o200)).unwrap();
    // Emptied while its daemon lives (which may die of it), so that no other process has
    // it mapped: every process that cleans up after dead nodes maps their segments, and
    // emptying one under it would be a SIGBUS there. Then the daemon dies.
    daemon.signal("KILL");
    let _ = wait(&mut daemon, 1);
    // `kerf status` says that no daemon answers (within `Env::kerf`'s patience) and the
    // segment is gone.
    let out = env.kerf("status", &[]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("no kerfd answers"));
    assert!(!segment.exists(), "{segment:?} is still there");
    // A new daemon starts and runs a program.
    let _daemon = env.start_daemon("kerfd-again");
    let program = env.write("short.ngc", "G21 G90\nG1 X2 Y1 F3000\nG0 X0 Y0\nM2\n");
    env.run_ok("run", &program, None);
}

/// The CPUs a thread of process `pid` whose name starts with `name` may run on
/// (`Cpus_allowed_list` of /proc/PID/task/TID/status), one entry per such thread.
fn threads_cpus(pid: u32, name: &str) -> Vec<String> {
    let mut found = Vec::new();
    for task in fs::read_dir(format!("/proc/{pid}/task")).unwrap() {
        let dir = task.unwrap().path();
        let comm = read_text(&dir.join("comm"));
        if comm.trim().starts_with(name) {
            let status = read_text(&dir.join("status"));
            let cpus = status
                .lines()
                .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
                .unwrap_or_else(|| panic!("no Cpus_allowed_list for {comm}"));
            found.push(cpus.trim().to_owned());
        }
    }
    found
}

/// `daemon.cpu` and `daemon.cpu_latency_us` as the running process shows them: the cycle
/// (and its publishing helper) on the configured CPU, the control and planning threads
/// off it, and, as root, the CPU wake-up latency request held open in
/// /dev/cpu_dma_latency and named in the log (as another user, the log says why not).
#[test]
fn kerfd_keeps_its_other_threads_off_the_cycles_cpu_and_holds_its_latency_request() {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert!(
        cpus >= 2,
        "this test needs two CPUs (one for the cycle); this machine has {cpus}"
    );
    let env = Env::new("cpus", &[("# cpu = 3", "cpu = 1")]);
    let daemon = env.start_daemon("kerfd");
    let pid = daemon.pid();
    assert_eq!(threads_cpus(pid, "kerfd-cycle"), ["1"]);
    for name in ["kerfd-control", "kerfd-planning"] {
        let sets = threads_cpus(pid, name);
        assert_eq!(sets.len(), 1, "{name}: {sets:?}");
        let allowed: Vec<usize> = sets[0]
            .split(',')
            .flat_map(|r| match r.split_once('-') {
                Some((a, b)) => (a.parse::<usize>().unwrap()..=b.parse().unwrap()).collect(),
                None => vec![r.parse::<usize>().unwrap()],
            })
            .collect();
        assert!(
            !allowed.is_empty() && !allowed.contains(&1),
            "{name} may run on CPUs {} (the cycle's is 1)",
            sets[0]
        );
    }
    let root = std::os::unix::fs::MetadataExt::uid(&fs::metadata("/proc/self").unwrap()) == 0;
    let held = fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .filter_map(|e| fs::read_link(e.unwrap().path()).ok())
        .any(|target| target == Path::new("/dev/cpu_dma_latency"));
    let log = daemon.stderr();
    if root {
        assert!(held, "kerfd holds no /dev/cpu_dma_latency open: {log}");
        assert!(log.contains("CPU wake-up latency 0 µs"), "{log}");
    } else {
        assert!(!held);
        assert!(log.contains("CPU wake-up latency of 0 µs refused"), "{log}");
    }
}
