//! `rt_setup` on a spawned thread, checked against what the kernel reports afterwards.

use kerf_rt::{RtConfig, RtError, avoid_cpu, rt_setup};

fn current_policy_and_priority() -> (libc::c_int, libc::c_int) {
    let mut policy = 0;
    // SAFETY: a zeroed sched_param is valid; both out-pointers are writable.
    let mut param: libc::sched_param = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param) };
    assert_eq!(rc, 0);
    (policy, param.sched_priority)
}

fn allowed_cpus() -> Vec<usize> {
    // SAFETY: a zeroed cpu_set_t is a valid out-parameter.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::sched_getaffinity(0, size_of::<libc::cpu_set_t>(), &mut set) };
    assert_eq!(rc, 0);
    (0..libc::CPU_SETSIZE as usize)
        // SAFETY: i < CPU_SETSIZE.
        .filter(|&i| unsafe { libc::CPU_ISSET(i, &set) })
        .collect()
}

fn locked_kib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("read /proc/self/status");
    let line = status
        .lines()
        .find(|l| l.starts_with("VmLck:"))
        .expect("VmLck line");
    line.split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .expect("VmLck value")
}

fn cpu_count() -> usize {
    // SAFETY: sysconf takes a constant only.
    unsafe { libc::sysconf(libc::_SC_NPROCESSORS_CONF) as usize }
}

// One test function: mlockall and its undoing are process-wide.
#[test]
fn rt_setup_does_what_it_reports_and_rejects_bad_arguments() {
    // Invalid arguments are errors, and change nothing on the thread.
    std::thread::spawn(|| {
        let before = (current_policy_and_priority(), allowed_cpus());
        for priority in [0u8, 100, 255] {
            let config = RtConfig {
                priority: Some(priority),
                cpu: None,
                prefault_stack_bytes: 0,
            };
            assert!(matches!(
                rt_setup(&config),
                Err(RtError::InvalidPriority { priority: p }) if p == priority
            ));
        }
        let config = RtConfig {
            priority: Some(10),
            cpu: Some(cpu_count()),
            prefault_stack_bytes: 0,
        };
        assert!(matches!(rt_setup(&config), Err(RtError::InvalidCpu { .. })));
        // Larger than any thread stack the test harness makes (2 MiB by default, 8 MiB main).
        let config = RtConfig {
            priority: None,
            cpu: None,
            prefault_stack_bytes: 1 << 30,
        };
        assert!(matches!(
            rt_setup(&config),
            Err(RtError::StackTooSmall { .. })
        ));
        assert_eq!((current_policy_and_priority(), allowed_cpus()), before);
    })
    .join()
    .expect("validation thread");

    // A valid request: whatever the report says took effect, did; what it says was refused
    // comes with a message.
    let last_cpu = cpu_count() - 1;
    let report = std::thread::Builder::new()
        .stack_size(1 << 20)
        .spawn(move || {
            let config = RtConfig {
                priority: Some(7),
                cpu: Some(last_cpu),
                prefault_stack_bytes: 256 * 1024,
            };
            let report = rt_setup(&config).expect("valid configuration");
            let (policy, priority) = current_policy_and_priority();
            if report.fifo {
                assert_eq!((policy, priority), (libc::SCHED_FIFO, 7));
            } else {
                assert_eq!(policy, libc::SCHED_OTHER);
            }
            if report.timer_slack {
                // SAFETY: PR_GET_TIMERSLACK takes no argument and returns the slack in ns.
                let slack_ns = unsafe { libc::prctl(libc::PR_GET_TIMERSLACK) };
                // 1 ns as set; 0 once SCHED_FIFO is in force on kernels that zero the slack
                // of real-time threads. Either way no longer the 50 µs default.
                assert!((0..=1).contains(&slack_ns), "timer slack {slack_ns} ns");
            }
            if report.affinity {
                assert_eq!(allowed_cpus(), vec![last_cpu]);
            }
            report
        })
        .expect("spawn")
        .join()
        .expect("set-up thread");
    if report.mlocked {
        assert!(locked_kib() > 0, "mlockall reported but nothing is locked");
    }
    let refused = [
        report.mlocked,
        report.fifo,
        report.affinity,
        report.timer_slack,
    ]
    .iter()
    .filter(|ok| !**ok)
    .count();
    assert_eq!(report.messages.len(), refused, "{:?}", report.messages);
    assert_eq!(report.is_realtime(), report.mlocked && report.fifo);

    // SAFETY: undoes this test's mlockall for the rest of the process.
    unsafe { libc::munlockall() };
}

/// `avoid_cpu` takes the one CPU out of the thread's set, leaves the set alone when the
/// CPU is not in it or is the only one, and threads started afterwards inherit it.
#[test]
fn avoid_cpu_keeps_the_thread_and_its_children_off_the_cycles_cpu() {
    std::thread::spawn(|| {
        let all = allowed_cpus();
        assert!(!all.is_empty());
        if all.len() >= 2 {
            let cycle = all[all.len() - 1];
            assert!(avoid_cpu(cycle).unwrap());
            let rest: Vec<usize> = all.iter().copied().filter(|&c| c != cycle).collect();
            assert_eq!(allowed_cpus(), rest);
            let child = std::thread::spawn(allowed_cpus).join().unwrap();
            assert_eq!(child, rest, "a thread started afterwards");
            // Not in the set any more: nothing changes.
            assert!(!avoid_cpu(cycle).unwrap());
            assert_eq!(allowed_cpus(), rest);
        }
        // The only CPU left is kept.
        let only = allowed_cpus();
        let mut last = only.clone();
        for &c in &only[..only.len() - 1] {
            assert!(avoid_cpu(c).unwrap());
            last.retain(|&x| x != c);
        }
        assert_eq!(allowed_cpus(), last);
        assert!(!avoid_cpu(last[0]).unwrap());
        assert_eq!(allowed_cpus(), last);
        // A CPU index beyond any set.
        assert!(!avoid_cpu(1 << 20).unwrap());
    })
    .join()
    .unwrap();
}
