//! The checks of each target, and what they share.
//!
//! The stream decoders' inputs are laid out as `[n_chunk_sizes, chunk sizes..., (target
//! parameters...), stream]`: the stream is pushed in those chunk sizes (cycled), events are
//! drained after every push, and at the end the decoder is flushed ([`check_stream`]). The file
//! readers' inputs are `[cut (u16, little-endian), file...]` ([`files`]).

pub(crate) mod cdr;
pub(crate) mod command;
mod files;
pub(crate) mod mcap;
pub(crate) mod mip;
pub(crate) mod reply;
pub(crate) mod ros1_bag;
pub(crate) mod ros1_message;
pub(crate) mod ros2_db3;
pub(crate) mod ros2_frame;
pub(crate) mod vectornav;
pub(crate) mod xsens;

pub(crate) use files::with_cut;

/// Splits the leading chunk sizes (at most 7) off an input.
pub(crate) fn split_chunk_sizes(data: &[u8]) -> Option<(&[u8], &[u8])> {
    let (&n_sizes, rest) = data.split_first()?;
    let n_sizes = usize::from(n_sizes % 8).min(rest.len());
    Some(rest.split_at(n_sizes))
}

/// Pushes `stream` in the cycled `sizes` (the whole stream at once when there are none), calling
/// `push` for each chunk.
fn push_in_chunks(stream: &[u8], sizes: &[u8], mut push: impl FnMut(&[u8])) {
    let mut at = 0;
    let mut i = 0;
    while at < stream.len() {
        let size = sizes
            .get(i % sizes.len().max(1))
            .map_or(stream.len(), |&s| usize::from(s).max(1));
        let end = (at + size).min(stream.len());
        push(&stream[at..end]);
        at = end;
        i += 1;
    }
}

/// A push-bytes, pull-events decoder that reports every byte once.
pub(crate) trait Stream {
    /// What it reports.
    type Event;
    /// Bytes read from the stream.
    fn push(&mut self, bytes: &[u8]);
    /// The stream ended.
    fn flush(&mut self);
    /// The next event, if any.
    fn next_event(&mut self) -> Option<Self::Event>;
    /// Bytes held and not yet reported.
    fn pending_len(&self) -> usize;
    /// Its counters: bytes in, bytes of accepted frames (or commands), rejected bytes.
    fn counters(&self) -> (u64, u64, u64);
    /// Checks one event (panics if it is wrong) and appends the stream bytes it stands for to
    /// `rebuilt`, which holds the bytes of every earlier event.
    fn account(event: Self::Event, rebuilt: &mut Vec<u8>);
}

/// Implements [`Stream`] for a decoder whose inherent methods have the trait's names and whose
/// stats have `bytes_in`, `rejected_bytes` and `$accepted`; `$account` is the trait's `account`.
macro_rules! stream {
    ($decoder:ty, $event:ty, $accepted:ident, $account:expr) => {
        impl $crate::targets::Stream for $decoder {
            type Event = $event;
            fn push(&mut self, bytes: &[u8]) {
                <$decoder>::push(self, bytes);
            }
            fn flush(&mut self) {
                <$decoder>::flush(self);
            }
            fn next_event(&mut self) -> Option<$event> {
                <$decoder>::next_event(self)
            }
            fn pending_len(&self) -> usize {
                <$decoder>::pending_len(self)
            }
            fn counters(&self) -> (u64, u64, u64) {
                let s = self.stats();
                (s.bytes_in, s.$accepted, s.rejected_bytes)
            }
            fn account(ev: $event, rebuilt: &mut Vec<u8>) {
                $account(ev, rebuilt);
            }
        }
    };
}
pub(crate) use stream;

/// Asserts that an event's bytes start where the previous event's ended and are not empty.
pub(crate) fn assert_contiguous(offset: u64, bytes: &[u8], rebuilt: &[u8]) {
    assert_eq!(offset, rebuilt.len() as u64, "events are contiguous");
    assert!(!bytes.is_empty(), "no empty events");
}

/// Pushes `stream` into `d` in the cycled chunk `sizes`, draining after every push, then
/// flushes: every byte is reported exactly once and in order (the events rebuild the stream),
/// and the counters account for every byte at every step.
pub(crate) fn check_stream<D: Stream>(mut d: D, sizes: &[u8], stream: &[u8]) {
    let mut rebuilt = Vec::with_capacity(stream.len());
    push_in_chunks(stream, sizes, |chunk| {
        d.push(chunk);
        drain(&mut d, &mut rebuilt);
    });
    d.flush();
    drain(&mut d, &mut rebuilt);
    assert_eq!(d.pending_len(), 0, "flush reports everything");
    assert_eq!(rebuilt, stream, "events rebuild the stream");
}

fn drain<D: Stream>(d: &mut D, rebuilt: &mut Vec<u8>) {
    while let Some(ev) = d.next_event() {
        D::account(ev, rebuilt);
    }
    let (bytes_in, accepted, rejected) = d.counters();
    let pending = d.pending_len() as u64;
    assert_eq!(
        bytes_in,
        rebuilt.len() as u64 + pending,
        "conservation: bytes in = bytes reported + pending"
    );
    assert_eq!(
        bytes_in,
        accepted + rejected + pending,
        "conservation: bytes in = accepted + rejected + pending"
    );
}
