//! The per-frame path's hand-off to the DDS thread: a bounded lock-free single-producer
//! single-consumer ring (`rtrb`) and a park/unpark wake-up that costs the producer one atomic swap
//! while the consumer is busy, and one `unpark` (a futex wake) only when it sleeps.
//!
//! Why not `std::sync::mpsc::sync_channel`: its receiver registers in a mutex-guarded waker list
//! whenever the queue is empty, and the sender takes that mutex to wake it; at 1 kHz the two
//! threads met on it for about two samples in three (`perf` of `cargo bench -p imud --bench
//! ros2`), each meeting a futex sleep and wake of the DDS thread on top of the one a sample needs.
//!
//! The wake-up is the classic flag-and-recheck: the consumer announces it will park, then looks
//! at the ring again; the producer pushes, then takes the announcement. A `SeqCst` fence on each
//! side orders each side's store before its load, so at least one of them sees the other's: either
//! the consumer finds the item, or the producer finds the flag and unparks (an unpark before the
//! park makes the park return at once).

use std::cell::RefCell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering, fence};
use std::thread::Thread;
use std::time::{Duration, Instant};

/// Flags both ends share.
#[derive(Debug, Default)]
struct Flags {
    /// The consumer is parked, or about to park.
    parked: AtomicBool,
    /// The producer is done: the consumer ends once the ring is empty.
    closed: AtomicBool,
}

/// A bounded queue of `capacity` items from one producer to one consumer thread.
pub(super) fn channel<T>(capacity: usize) -> (UnboundSender<T>, Receiver<T>) {
    let (producer, consumer) = rtrb::RingBuffer::new(capacity);
    let flags = Arc::new(Flags::default());
    (
        UnboundSender {
            producer,
            flags: flags.clone(),
        },
        Receiver { consumer, flags },
    )
}

/// The producer end before the consumer thread exists.
pub(super) struct UnboundSender<T> {
    producer: rtrb::Producer<T>,
    flags: Arc<Flags>,
}

impl<T> UnboundSender<T> {
    /// The producer end, waking `consumer` (the thread that owns the [`Receiver`]).
    pub(super) fn bind(self, consumer: Thread) -> Sender<T> {
        Sender {
            producer: RefCell::new(self.producer),
            flags: self.flags,
            consumer,
        }
    }
}

/// The producer end: the per-frame path (one thread; `RefCell` because the sinks are shared by
/// reference along that path).
pub(super) struct Sender<T> {
    producer: RefCell<rtrb::Producer<T>>,
    flags: Arc<Flags>,
    consumer: Thread,
}

impl<T> Sender<T> {
    /// Queues `item` and wakes the consumer if it sleeps; false when the queue was full (the
    /// item is dropped). Never blocks.
    pub(super) fn try_send(&self, item: T) -> bool {
        if self.producer.borrow_mut().push(item).is_err() {
            return false;
        }
        self.wake();
        true
    }

    fn wake(&self) {
        // Orders the push before reading the flag (see the module comment).
        fence(Ordering::SeqCst);
        if self.flags.parked.swap(false, Ordering::SeqCst) {
            self.consumer.unpark();
        }
    }

    /// No more items: the consumer takes what is queued, then ends.
    pub(super) fn close(self) {
        self.flags.closed.store(true, Ordering::SeqCst);
        self.consumer.unpark();
    }
}

/// The consumer end, owned by the DDS thread.
pub(super) struct Receiver<T> {
    consumer: rtrb::Consumer<T>,
    flags: Arc<Flags>,
}

/// What [`Receiver::next`] found.
pub(super) enum Next<T> {
    /// An item.
    Item(T),
    /// Nothing within the timeout.
    Idle,
    /// The producer closed and everything queued was taken.
    Closed,
}

impl<T> Receiver<T> {
    /// The next item, waiting for one up to `timeout`. [`Next::Idle`] means the whole timeout
    /// passed with nothing queued: a park that returns early (an unpark token left by a wake-up
    /// the consumer did not need, or a spurious return) parks again for the time left.
    pub(super) fn next(&mut self, timeout: Duration) -> Next<T> {
        if let Ok(item) = self.consumer.pop() {
            return Next::Item(item);
        }
        let deadline = Instant::now() + timeout;
        loop {
            if self.flags.closed.load(Ordering::SeqCst) {
                // The producer pushed everything before it closed.
                return match self.consumer.pop() {
                    Ok(item) => Next::Item(item),
                    Err(_) => Next::Closed,
                };
            }
            let Some(left) = deadline.checked_duration_since(Instant::now()) else {
                return Next::Idle;
            };
            self.flags.parked.store(true, Ordering::SeqCst);
            // Orders the flag before looking at the ring again (see the module comment).
            fence(Ordering::SeqCst);
            if self.consumer.is_empty() && !self.flags.closed.load(Ordering::SeqCst) {
                std::thread::park_timeout(left);
            }
            self.flags.parked.store(false, Ordering::SeqCst);
            if let Ok(item) = self.consumer.pop() {
                return Next::Item(item);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every item arrives once and in order while the consumer keeps parking (a producer that
    /// pauses now and then), and closing ends the consumer after the last item.
    #[test]
    fn no_item_is_lost_or_stuck_across_parks() {
        const N: u64 = 200_000;
        let (tx, mut rx) = channel::<u64>(64);
        let consumer = std::thread::spawn(move || {
            let mut next = 0u64;
            loop {
                // A long timeout: a lost wake-up shows as a stall, and the test's time as a
                // failure to finish, not as a slow pass.
                match rx.next(Duration::from_secs(30)) {
                    Next::Item(v) => {
                        assert_eq!(v, next, "items out of order or lost");
                        next += 1;
                    }
                    Next::Idle => panic!("a wake-up was lost: idle for 30 s with items queued"),
                    Next::Closed => return next,
                }
            }
        });
        let tx = tx.bind(consumer.thread().clone());
        let mut v = 0;
        while v < N {
            if tx.try_send(v) {
                v += 1;
                if v % 1000 == 0 {
                    // Let the consumer empty the ring and park.
                    std::thread::sleep(Duration::from_micros(50));
                }
            } else {
                if consumer.is_finished() {
                    // It failed and left the ring full: its join below says why.
                    break;
                }
                std::thread::yield_now();
            }
        }
        tx.close();
        assert_eq!(consumer.join().unwrap(), N);
    }

    #[test]
    fn a_full_queue_refuses_and_keeps_what_it_has() {
        let (tx, mut rx) = channel::<u32>(2);
        let tx = tx.bind(std::thread::current());
        assert!(tx.try_send(1) && tx.try_send(2));
        assert!(!tx.try_send(3));
        tx.close();
        let mut got = Vec::new();
        while let Next::Item(v) = rx.next(Duration::from_millis(1)) {
            got.push(v);
        }
        assert_eq!(got, [1, 2]);
        assert!(matches!(rx.next(Duration::from_millis(1)), Next::Closed));
    }

    /// An unpark token left over from a wake-up the consumer did not need (the producer saw the
    /// flag of a park that found an item) makes the next park return at once; `next` parks again
    /// for the rest of the timeout instead of reporting an idle timeout that did not happen.
    #[test]
    fn a_leftover_wake_up_is_not_an_idle_timeout() {
        let (tx, mut rx) = channel::<u32>(2);
        let _tx = tx.bind(std::thread::current());
        std::thread::current().unpark();
        let timeout = Duration::from_millis(20);
        let start = Instant::now();
        assert!(matches!(rx.next(timeout), Next::Idle));
        assert!(
            start.elapsed() >= timeout,
            "idle after {:?}",
            start.elapsed()
        );
    }
}
