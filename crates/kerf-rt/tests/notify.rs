//! The systemd notify functions against a notify socket made by the test, as systemd would
//! provide one. One test per file: it sets the process environment.

use std::os::unix::net::UnixDatagram;
use std::time::Duration;

use kerf_rt::{Watchdog, notify_ready, notify_stopping, notify_watchdog, watchdog_interval};

fn received(socket: &UnixDatagram) -> Vec<String> {
    let mut messages = Vec::new();
    let mut buf = [0u8; 512];
    while let Ok(n) = socket.recv(&mut buf) {
        messages.push(String::from_utf8_lossy(&buf[..n]).into_owned());
    }
    messages
}

#[test]
fn notifications_reach_the_socket_only_under_systemd() {
    // SAFETY (for every set_var/remove_var below): this file's single test is the only
    // thread of the process that touches the environment.
    unsafe {
        std::env::remove_var("NOTIFY_SOCKET");
        std::env::remove_var("WATCHDOG_USEC");
        std::env::remove_var("WATCHDOG_PID");
    }
    // Outside systemd: no-ops that succeed.
    notify_ready().expect("no-op ready");
    notify_watchdog().expect("no-op watchdog");
    notify_stopping().expect("no-op stopping");
    assert_eq!(watchdog_interval(), None);
    let mut watchdog = Watchdog::new();
    assert!(!watchdog.feed(1).expect("no-op feed"));
    assert!(watchdog.feed(2).expect("no-op feed"));

    let dir = std::env::temp_dir().join(format!("kerf-rt-notify-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("notify.sock");
    let _ = std::fs::remove_file(&path);
    let socket = UnixDatagram::bind(&path).expect("bind notify socket");
    socket.set_nonblocking(true).expect("non-blocking");
    unsafe { std::env::set_var("NOTIFY_SOCKET", &path) };

    notify_ready().expect("ready");
    notify_stopping().expect("stopping");
    assert_eq!(received(&socket), ["READY=1\n", "STOPPING=1\n"]);

    // The watchdog helper sends only when the cycle counter moved since the previous call.
    let mut watchdog = Watchdog::new();
    let sent: Vec<bool> = [10u64, 10, 11, 11, 11, 12]
        .iter()
        .map(|&cycles| watchdog.feed(cycles).expect("feed"))
        .collect();
    assert_eq!(sent, [false, false, true, false, false, true]);
    assert_eq!(received(&socket), ["WATCHDOG=1\n", "WATCHDOG=1\n"]);

    // The watchdog interval applies only to the process systemd named.
    unsafe {
        std::env::set_var("WATCHDOG_USEC", "1000000");
        std::env::set_var("WATCHDOG_PID", std::process::id().to_string());
    }
    assert_eq!(watchdog_interval(), Some(Duration::from_secs(1)));
    unsafe { std::env::set_var("WATCHDOG_PID", (std::process::id() + 1).to_string()) };
    assert_eq!(watchdog_interval(), None);

    drop(socket);
    let _ = std::fs::remove_dir_all(&dir);
}
