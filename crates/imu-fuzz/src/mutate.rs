//! A seeded mutator for the stable harness: corpus inputs changed by a few byte-level edits
//! (bit flips, random and protocol bytes, insertions, deletions, duplicated and spliced ranges,
//! truncation). Deterministic for a seed, so a CI failure is reproduced by its seed and count.
//! It has no coverage feedback; the cargo-fuzz targets in `fuzz/` are the coverage-guided run.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::Target;

/// Longest input the mutator makes (longer than any frame, short enough to keep a run fast).
pub const MAX_INPUT_LEN: usize = 4096;

/// Bytes that mean something to the decoders: GX1 reply/command codes and their argument bytes,
/// MIP's sync bytes and descriptor sets, VectorNav's sync and group bytes and sentence pieces,
/// and edge values of lengths and counters.
fn dictionary(target: Target) -> &'static [&'static [u8]] {
    match target {
        Target::ReplyDecoder | Target::CommandDecoder => &[
            &[0x01],
            &[0x02],
            &[0x03],
            &[0x0C],
            &[0x10, 0x00],
            &[0x0F, 0xC1, 0xC3, 0xC5],
            &[0x28, 0x00, 0xE6],
            &[0x29, 0x71],
            &[0x31],
            &[0xF0],
            &[0xF1],
            &[0xFF, 0xFF],
            &[0x00, 0x00],
            &[0x80, 0x00],
        ],
        Target::MipDecoder => &[
            &[0x75, 0x65],
            &[0x75, 0x65, 0x80],
            &[0x75, 0x65, 0x01],
            &[0x75, 0x65, 0x0C],
            &[0x75],
            &[0x80],
            &[0xFF],
            &[0x00],
            &[0x0E, 0x04],
            &[0x06, 0xD3],
            &[0xF1],
        ],
        Target::VectornavDecoder => &[
            &[0xFA],
            &[0xFA, 0x01],
            &[0xFA, 0x07],
            &[0xFA, 0x80],
            &[0xFF, 0x87],
            b"$VN",
            b"$VNRRG,",
            b"$VNWRG,75,",
            b"$VNERR,",
            b"*XX\r\n",
            b"*",
            b"\r\n",
            b",",
            &[0x00],
        ],
    }
}

/// Makes mutated inputs from a corpus, deterministically for a seed.
pub struct Mutator {
    rng: ChaCha8Rng,
    target: Target,
}

impl Mutator {
    /// A mutator for `target`'s inputs, seeded.
    pub fn new(target: Target, seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            target,
        }
    }

    /// Writes into `out` a new input: one in 16 fully random, the rest a corpus entry with one to
    /// four edits (an empty corpus gives random inputs only).
    pub fn next_input(&mut self, corpus: &[Vec<u8>], out: &mut Vec<u8>) {
        out.clear();
        if corpus.is_empty() || self.rng.random_ratio(1, 16) {
            let len = self.rng.random_range(0..=256);
            out.extend((0..len).map(|_| self.rng.random::<u8>()));
            return;
        }
        out.extend_from_slice(&corpus[self.rng.random_range(0..corpus.len())]);
        for _ in 0..self.rng.random_range(1..=4) {
            let other = &corpus[self.rng.random_range(0..corpus.len())];
            self.edit(out, other);
        }
        out.truncate(MAX_INPUT_LEN);
    }

    fn edit(&mut self, data: &mut Vec<u8>, other: &[u8]) {
        let rng = &mut self.rng;
        let len = data.len();
        match rng.random_range(0..8u8) {
            0 if len > 0 => {
                let i = rng.random_range(0..len);
                data[i] ^= 1 << rng.random_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.random_range(0..len);
                data[i] = rng.random();
            }
            2 => {
                let at = rng.random_range(0..=len);
                let n = rng.random_range(1..=8);
                let bytes: Vec<u8> = (0..n).map(|_| rng.random()).collect();
                data.splice(at..at, bytes);
            }
            3 if len > 0 => {
                let start = rng.random_range(0..len);
                let end = rng.random_range(start..=len.min(start + 64));
                data.drain(start..end);
            }
            4 if len > 0 => {
                let start = rng.random_range(0..len);
                let end = rng.random_range(start..=len.min(start + 64));
                let at = rng.random_range(0..=len);
                let copy = data[start..end].to_vec();
                data.splice(at..at, copy);
            }
            5 if !other.is_empty() => {
                let start = rng.random_range(0..other.len());
                let end = rng.random_range(start..=other.len());
                let at = rng.random_range(0..=len);
                data.splice(at..at, other[start..end].iter().copied());
            }
            6 => {
                let dict = dictionary(self.target);
                let token = dict[rng.random_range(0..dict.len())];
                let at = rng.random_range(0..=len);
                if rng.random_bool(0.5) || at + token.len() > len {
                    data.splice(at..at, token.iter().copied());
                } else {
                    data[at..at + token.len()].copy_from_slice(token);
                }
            }
            _ if len > 0 => data.truncate(rng.random_range(0..len)),
            _ => data.push(rng.random()),
        }
    }
}
