//! Who controls the machine: one client at a time may (the holder of the control lease),
//! the others watch.
//!
//! A client names itself with the `Kerf-Client` header (an id it makes up, such as the
//! page's random one per tab) and takes the lease with `POST /api/v1/control/lease`
//! (`{"action":"take"}`). While another client holds it, a request that could start or
//! change motion (cycle start, jog, homing, a program, MDI, overrides, reset, switches) is
//! refused with `controlled_elsewhere`; stopping the machine (hold, abort, jog stop) is
//! always allowed to everyone who may control at all, as the feed-hold and emergency
//! buttons of every station of a machine are. While nobody holds the lease, every
//! authorised client may control, so a script that never takes it keeps working on a
//! machine nobody watches.
//!
//! The lease lapses [`LEASE_TTL`] after the holder's last control request or renewal (the
//! page renews it every few seconds while the tab is open, so a closed tab or a lost
//! network frees it), or when the holder releases it. Another client can take it over with
//! `"force": true` (the operator at the machine when the holder walked away); the former
//! holder's next request is refused and the take-over is logged.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// How long the lease lasts after its holder's last request.
pub const LEASE_TTL: Duration = Duration::from_secs(10);

/// The holder of the lease.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Holder {
    /// The id it gave in `Kerf-Client`.
    pub client: String,
    /// Where its request that took the lease came from.
    pub peer: SocketAddr,
    /// When it took the lease.
    pub since: Instant,
    /// When it last renewed it (took it again or sent a control request).
    pub renewed: Instant,
}

/// The control lease of one `kerf serve`.
#[derive(Debug, Default)]
pub struct Lease {
    holder: Option<Holder>,
}

/// Whether `id` is a client id: 8 to 64 of `A-Z a-z 0-9 -`.
pub fn valid_client(id: &str) -> bool {
    (8..=64).contains(&id.len()) && id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
}

impl Lease {
    /// The holder at `now`, if the lease has not lapsed.
    pub fn holder(&self, now: Instant) -> Option<&Holder> {
        self.holder
            .as_ref()
            .filter(|h| now.saturating_duration_since(h.renewed) < LEASE_TTL)
    }

    /// `client` (from `peer`) takes or renews the lease at `now`; with `force` even from
    /// another holder. Err: the holder that keeps it.
    pub fn take(
        &mut self,
        client: &str,
        peer: SocketAddr,
        force: bool,
        now: Instant,
    ) -> Result<(), Holder> {
        match self.holder(now) {
            Some(h) if h.client == client => {
                if let Some(h) = self.holder.as_mut() {
                    h.renewed = now;
                }
                Ok(())
            }
            Some(h) if !force => Err(h.clone()),
            _ => {
                self.holder = Some(Holder {
                    client: client.to_owned(),
                    peer,
                    since: now,
                    renewed: now,
                });
                Ok(())
            }
        }
    }

    /// `client` gives the lease back; whether it held it.
    pub fn release(&mut self, client: &str, now: Instant) -> bool {
        if self.holder(now).is_some_and(|h| h.client == client) {
            self.holder = None;
            true
        } else {
            false
        }
    }

    /// Whether a control request of `client` (None: it gave no id) may go on at `now`;
    /// `stops`: the request only stops motion (always allowed). A request of the holder
    /// renews the lease. Err: the holder that keeps it.
    pub fn permits(
        &mut self,
        client: Option<&str>,
        stops: bool,
        now: Instant,
    ) -> Result<(), Holder> {
        match self.holder(now) {
            None => Ok(()),
            Some(h) if Some(h.client.as_str()) == client => {
                if let Some(h) = self.holder.as_mut() {
                    h.renewed = now;
                }
                Ok(())
            }
            Some(_) if stops => Ok(()),
            Some(h) => Err(h.clone()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn peer(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    #[test]
    fn one_client_controls_others_only_stop_and_a_forced_take_over_moves_the_lease() {
        let t0 = Instant::now();
        let mut lease = Lease::default();
        // Nobody holds it: everyone may control.
        assert!(lease.permits(None, false, t0).is_ok());
        assert!(lease.permits(Some("page-bbbbbbbb"), false, t0).is_ok());
        lease.take("page-aaaaaaaa", peer(1), false, t0).unwrap();
        assert!(lease.permits(Some("page-aaaaaaaa"), false, t0).is_ok());
        let other = lease.permits(Some("page-bbbbbbbb"), false, t0).unwrap_err();
        assert_eq!(
            (other.client.as_str(), other.peer),
            ("page-aaaaaaaa", peer(1))
        );
        assert!(
            lease.permits(None, false, t0).is_err(),
            "an anonymous client"
        );
        assert!(
            lease.permits(Some("page-bbbbbbbb"), true, t0).is_ok(),
            "a stop"
        );
        // Without force the lease stays; with it, it moves.
        assert!(lease.take("page-bbbbbbbb", peer(2), false, t0).is_err());
        lease.take("page-bbbbbbbb", peer(2), true, t0).unwrap();
        assert!(lease.permits(Some("page-aaaaaaaa"), false, t0).is_err());
        assert!(!lease.release("page-aaaaaaaa", t0), "not the holder");
        assert!(lease.release("page-bbbbbbbb", t0));
        assert!(lease.holder(t0).is_none());
        assert!(lease.permits(Some("page-aaaaaaaa"), false, t0).is_ok());
    }

    #[test]
    fn the_lease_lapses_a_ttl_after_the_holders_last_request() {
        let t0 = Instant::now();
        let mut lease = Lease::default();
        lease.take("page-aaaaaaaa", peer(1), false, t0).unwrap();
        // A request of the holder renews it.
        let t1 = t0 + LEASE_TTL - Duration::from_millis(1);
        assert!(lease.permits(Some("page-aaaaaaaa"), false, t1).is_ok());
        let t2 = t0 + LEASE_TTL + Duration::from_millis(1);
        assert!(
            lease.permits(Some("page-bbbbbbbb"), false, t2).is_err(),
            "renewed at t1"
        );
        let t3 = t1 + LEASE_TTL;
        assert!(lease.holder(t3).is_none(), "lapsed");
        assert!(lease.permits(Some("page-bbbbbbbb"), false, t3).is_ok());
        lease.take("page-bbbbbbbb", peer(2), false, t3).unwrap();
        assert_eq!(lease.holder(t3).unwrap().since, t3);
    }

    #[test]
    fn client_ids_are_short_plain_words() {
        assert!(valid_client("page-0123abcd"));
        assert!(valid_client(&"a".repeat(64)));
        for bad in ["", "short", "with space1", "ü-0123456789", &"a".repeat(65)] {
            assert!(!valid_client(bad), "{bad}");
        }
    }
}
