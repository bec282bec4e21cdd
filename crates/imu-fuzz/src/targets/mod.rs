//! The checks of each decoder. Every input is laid out as `[n_chunk_sizes, chunk sizes...,
//! (target parameters...), stream]`: the stream is pushed in those chunk sizes (cycled), events
//! are drained after every push, and at the end the decoder is flushed.

mod command;
mod mip;
mod reply;
mod vectornav;

pub(crate) use command::command_decoder;
pub(crate) use mip::mip_decoder;
pub(crate) use reply::reply_decoder;
pub(crate) use vectornav::vectornav_decoder;

/// Splits the leading chunk sizes (at most 7) off an input.
fn split_chunk_sizes(data: &[u8]) -> Option<(&[u8], &[u8])> {
    let (&n_sizes, rest) = data.split_first()?;
    let n_sizes = usize::from(n_sizes % 8).min(rest.len());
    Some(rest.split_at(n_sizes))
}

/// Pushes `stream` in the cycled `sizes` (the whole stream at once when there are none), calling
/// `push` for each chunk and `drain` after it.
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
