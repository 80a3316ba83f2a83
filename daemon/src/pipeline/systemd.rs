//! sd_notify: readiness, status line, watchdog and stopping, for
//! `Type=notify` units. Outside systemd (`NOTIFY_SOCKET` unset) every call is
//! a no-op, so `phyllo serve` runs the same from a terminal.

use std::time::Duration;

use sd_notify::NotifyState;

fn send(states: &[NotifyState<'_>]) {
    // A failed notification must never take the service down; systemd will
    // notice a missing READY or WATCHDOG by itself.
    if let Err(e) = sd_notify::notify(states) {
        tracing::debug!("sd_notify: {e}");
    }
}

/// Tells systemd the service is ready (after the store, model and watcher are up).
pub fn ready(status: &str) {
    send(&[NotifyState::Ready, NotifyState::Status(status)]);
}

/// Updates the one-line status shown by `systemctl status`.
pub fn status(status: &str) {
    send(&[NotifyState::Status(status)]);
}

/// Pings the watchdog.
pub fn watchdog() {
    send(&[NotifyState::Watchdog]);
}

/// Tells systemd that shutdown has begun.
pub fn stopping(status: &str) {
    send(&[NotifyState::Stopping, NotifyState::Status(status)]);
}

/// How often to ping the watchdog: half its timeout, if one is set for us.
pub fn watchdog_interval() -> Option<Duration> {
    sd_notify::watchdog_enabled().map(|d| d / 2)
}
