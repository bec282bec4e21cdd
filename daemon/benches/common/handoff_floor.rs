//! The floor under the DDS output's CPU: the thread hand-offs alone, with no encoding and no DDS.
//!
//! imud's DDS path per sample is: the pipeline thread unparks `imud-ros2` (the bounded queue's
//! wake-up), which writes to rustdds, whose `write` rings its event loop's waker (an eventfd), and
//! the event loop sends the datagram. This measures that shape with nothing else in it, so the
//! bench can say how much of the DDS threads' CPU is the hand-offs themselves:
//!
//! - two hops: a producer at `rate_hz` unparks thread A; A wakes thread B through a `mio` waker
//!   (B sleeps in `Poll::poll`, as rustdds's loop does); B sends one 400-byte UDP datagram to a
//!   receiver on 127.0.0.1.
//! - one hop: A sends the datagram itself (what a DDS library that sends on the writing thread
//!   would cost).
//!
//! The producer's own cost (the pipeline's in imud) is not counted, as it is not in the bench's
//! "DDS threads" figure.

use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::cpu_time::thread_cpu_ns;

/// How many threads the datagram passes through after the producer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hops {
    /// Producer -> A -> B -> socket.
    Two,
    /// Producer -> A -> socket.
    One,
}

const WAKER: mio::Token = mio::Token(0);
const DATAGRAM_BYTES: usize = 400;

/// On-CPU time of A and B together over `duration` at `rate_hz`, % of one core.
pub fn measure(hops: Hops, rate_hz: f64, duration: Duration) -> f64 {
    let receiver = UdpSocket::bind("127.0.0.1:0").expect("a loopback socket");
    let to = receiver.local_addr().expect("its address");
    let stop = Arc::new(AtomicBool::new(false));
    std::thread::Builder::new()
        .name("floor-peer".into())
        .spawn(move || {
            let mut buf = [0u8; 2048];
            while receiver.recv(&mut buf).is_ok_and(|n| n > 0) {}
        })
        .expect("spawn");
    let mut poll = mio::Poll::new().expect("an epoll instance");
    let waker = Arc::new(mio::Waker::new(poll.registry(), WAKER).expect("an eventfd"));
    let b = {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("floor-b".into())
            .spawn(move || {
                let socket = UdpSocket::bind("127.0.0.1:0").expect("a loopback socket");
                let datagram = [7u8; DATAGRAM_BYTES];
                let mut events = mio::Events::with_capacity(8);
                while !stop.load(Ordering::Relaxed) {
                    // A timeout, as rustdds's loop always has one (its timers).
                    let _ = poll.poll(&mut events, Some(Duration::from_millis(50)));
                    if events.iter().any(|e| e.token() == WAKER) {
                        let _ = socket.send_to(&datagram, to);
                    }
                }
            })
            .expect("spawn")
    };
    let a = {
        let stop = stop.clone();
        let waker = waker.clone();
        std::thread::Builder::new()
            .name("floor-a".into())
            .spawn(move || {
                let socket = UdpSocket::bind("127.0.0.1:0").expect("a loopback socket");
                let datagram = [7u8; DATAGRAM_BYTES];
                while !stop.load(Ordering::Relaxed) {
                    std::thread::park_timeout(Duration::from_millis(100));
                    match hops {
                        Hops::Two => waker.wake().expect("the eventfd"),
                        Hops::One => {
                            let _ = socket.send_to(&datagram, to);
                        }
                    }
                }
            })
            .expect("spawn")
    };
    let pid = std::process::id();
    let threads = || thread_cpu_ns(pid, |comm| comm == "floor-a" || comm == "floor-b");
    std::thread::sleep(Duration::from_millis(200));
    let (start, cpu0) = (Instant::now(), threads());
    let period = Duration::from_secs_f64(1.0 / rate_hz);
    let mut next = start;
    while start.elapsed() < duration {
        next += period;
        if let Some(wait) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        a.thread().unpark();
    }
    let (end, cpu1) = (Instant::now(), threads());
    stop.store(true, Ordering::Relaxed);
    a.thread().unpark();
    waker.wake().expect("the eventfd");
    a.join().expect("A ends");
    b.join().expect("B ends");
    // The peer thread blocks in recv; an empty datagram ends it.
    let _ = UdpSocket::bind("127.0.0.1:0").and_then(|s| s.send_to(&[], to));
    (cpu1 - cpu0) as f64 * 1e-9 / (end - start).as_secs_f64() * 100.0
}
