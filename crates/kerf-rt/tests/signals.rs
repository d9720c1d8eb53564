//! Raises real signals at the test process. One test per file: the recorded signal is
//! process-wide.

use kerf_rt::Signals;

fn raise(signal: libc::c_int) {
    // SAFETY: raise takes a signal number; the handlers installed below only store an atomic.
    assert_eq!(unsafe { libc::raise(signal) }, 0);
}

#[test]
fn sigterm_and_sigint_are_recorded_not_fatal() {
    let signals = Signals::install().expect("install handlers");
    assert_eq!(signals.stop_requested(), None);

    raise(libc::SIGTERM);
    // Still alive: the handler replaced the default action (terminate).
    assert_eq!(signals.stop_requested(), Some(libc::SIGTERM));
    // The first stop signal is the one reported.
    raise(libc::SIGINT);
    assert_eq!(signals.stop_requested(), Some(libc::SIGTERM));
    drop(signals);

    // A fresh installation starts clear and records SIGINT.
    let signals = Signals::install().expect("install handlers again");
    assert_eq!(signals.stop_requested(), None);
    raise(libc::SIGINT);
    assert_eq!(signals.stop_requested(), Some(libc::SIGINT));
    drop(signals);

    // Dropping restored the previous disposition (the default one here).
    // SAFETY: a zeroed sigaction is a valid out-parameter; a null new action only queries.
    let mut current: libc::sigaction = unsafe { std::mem::zeroed() };
    assert_eq!(
        unsafe { libc::sigaction(libc::SIGTERM, std::ptr::null(), &mut current) },
        0
    );
    assert_eq!(current.sa_sigaction, libc::SIG_DFL);
}
