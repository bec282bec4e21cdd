//! One command out and its reply awaited, tried [`TRIES`] times with a growing back-off between
//! tries: the request/retry rule every command-driven start-up (MIP, Xsens, VectorNav) follows.
//! What a reply is, and how a command is written, is the protocol's ([`Request`]); when to
//! resend and when to give up is decided here, once.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::{TRIES, back_off};

/// A command a start-up sends and awaits a reply to.
pub trait Request {
    /// The command's bytes on the wire.
    fn wire(&self) -> Vec<u8>;
    /// Why start-up fails when every try went unanswered within `timeout`.
    fn unanswered(&self, timeout: Duration) -> anyhow::Error;
}

/// One command out, until its reply comes or every try is used.
#[derive(Debug)]
pub struct Exchange<C> {
    /// The command.
    pub cmd: C,
    attempt: u32,
    /// Backing off until, or awaiting the reply until.
    until: Instant,
    awaiting: bool,
    timeout: Duration,
}

impl<C: Request> Exchange<C> {
    /// Sends `cmd` (into `tx`) at `now` and awaits its reply for `timeout`.
    pub fn new(cmd: C, timeout: Duration, now: Instant, tx: &mut VecDeque<Vec<u8>>) -> Self {
        tx.push_back(cmd.wire());
        Self {
            cmd,
            attempt: 0,
            until: now + timeout,
            awaiting: true,
            timeout,
        }
    }

    /// The command while its reply is awaited (not while backing off before a resend): a reply
    /// that arrives during the back-off answers nothing.
    pub fn awaited(&self) -> Option<&C> {
        self.awaiting.then_some(&self.cmd)
    }

    /// The next deadline: the end of the wait for the reply or of the back-off.
    pub fn until(&self) -> Instant {
        self.until
    }

    /// A deadline passed: the next try, or the error once all are used.
    pub fn on_timeout(
        &mut self,
        now: Instant,
        tx: &mut VecDeque<Vec<u8>>,
    ) -> Option<anyhow::Error> {
        if now < self.until {
            return None;
        }
        if !self.awaiting {
            tx.push_back(self.cmd.wire());
            self.awaiting = true;
            self.until = now + self.timeout;
            return None;
        }
        self.attempt += 1;
        if self.attempt >= TRIES {
            return Some(self.cmd.unanswered(self.timeout));
        }
        self.awaiting = false;
        self.until = now + back_off(self.attempt);
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Ping;

    impl Request for Ping {
        fn wire(&self) -> Vec<u8> {
            b"ping".to_vec()
        }
        fn unanswered(&self, timeout: Duration) -> anyhow::Error {
            anyhow::anyhow!("no pong within {:.1} s", timeout.as_secs_f64())
        }
    }

    #[test]
    fn tries_three_times_with_back_off_then_fails() {
        let t0 = Instant::now();
        let timeout = Duration::from_millis(500);
        let mut tx = VecDeque::new();
        let mut ex = Exchange::new(Ping, timeout, t0, &mut tx);
        assert_eq!(tx.len(), 1);
        assert!(ex.awaited().is_some());
        // Before the deadline nothing happens.
        assert!(ex.on_timeout(t0 + timeout / 2, &mut tx).is_none());
        assert_eq!(tx.len(), 1);
        let mut now = t0;
        let mut sends = vec![t0];
        for _ in 0..100 {
            now = ex.until();
            let before = tx.len();
            if let Some(e) = ex.on_timeout(now, &mut tx) {
                assert_eq!(e.to_string(), "no pong within 0.5 s");
                break;
            }
            if tx.len() > before {
                sends.push(now);
                assert!(ex.awaited().is_some());
            } else {
                // Backing off: a reply now answers nothing.
                assert!(ex.awaited().is_none());
            }
        }
        assert_eq!(sends.len() as u32, TRIES);
        // Each resend waits the timeout and then the back-off before it.
        for (k, w) in sends.windows(2).enumerate() {
            assert_eq!(w[1] - w[0], timeout + back_off(k as u32 + 1));
        }
        assert_eq!(now - sends[TRIES as usize - 1], timeout);
    }
}
