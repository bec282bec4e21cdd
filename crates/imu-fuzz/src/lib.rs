//! The decoders' and file readers' fuzz checks in one place: what every input must satisfy (no
//! panic; for the stream decoders every byte accounted for exactly once and events that rebuild
//! the stream; for the message decoders a truncated message never decodes and a decoded one
//! re-encodes to itself; for the file readers every message of a cut file is one of the whole
//! file's, in order, and a cut is never silent), run by the coverage-guided libFuzzer binary in
//! `fuzz/` and by this crate's stable-Rust harness ([`run()`]), which replays the committed
//! corpus (`fuzz/corpus/<target>/`) and seeded mutations of it.
//!
//! A check panics when an invariant breaks; the harness catches the panic and reports the input.
//! A new target is a module under `targets/` with a `pub static TARGET` and one line in [`ALL`].

use std::path::{Path, PathBuf};

pub mod corpus;
pub mod mutate;
pub mod run;
mod seeds;
mod targets;

pub use run::{Failure, RunReport, run};

/// One fuzz target: a decoder or reader, the checks its output must pass, where its corpus
/// starts and the bytes that mean something to it.
pub struct Target {
    /// The corpus directory's name and what `imu-fuzz run` and `scripts/fuzz` take.
    pub name: &'static str,
    /// What is fuzzed, for listings (`imu-fuzz list`).
    pub about: &'static str,
    /// Runs the checks on one input; panics if an invariant breaks.
    check: fn(&[u8]),
    /// The seed inputs (`imu-fuzz seed`), deterministic; `None` when the committed seeds come
    /// from another writer (said in `about`).
    seeds: Option<fn() -> Vec<Vec<u8>>>,
    /// Byte strings the mutator inserts (sync bytes, codes, edge values of lengths).
    pub dictionary: &'static [&'static [u8]],
    /// Mutations per run of the CI tier: the file readers go through a file per input, so
    /// they get fewer than the in-memory decoders.
    pub ci_mutations: u64,
}

/// Every target, in the order reports list them (one line each).
pub static ALL: &[&Target] = &[
    &targets::reply::TARGET,
    &targets::command::TARGET,
    &targets::mip::TARGET,
    &targets::xsens::TARGET,
    &targets::vectornav::TARGET,
    &targets::ros2_frame::TARGET,
    &targets::cdr::TARGET,
    &targets::ros1_message::TARGET,
    &targets::mcap::TARGET,
    &targets::ros1_bag::TARGET,
    &targets::ros2_db3::TARGET,
];

impl std::fmt::Debug for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name)
    }
}

impl Target {
    /// The target called `name`, if any.
    pub fn from_name(name: &str) -> Option<&'static Target> {
        ALL.iter().copied().find(|t| t.name == name)
    }

    /// Runs the target's checks on one input; panics if an invariant breaks.
    pub fn check(&self, data: &[u8]) {
        (self.check)(data);
    }

    /// The seed inputs a corpus starts from, or `None` when another writer made them.
    pub fn seeds(&self) -> Option<Vec<Vec<u8>>> {
        self.seeds.map(|f| f())
    }

    /// The committed corpus of this target: `fuzz/corpus/<name>/` in the source tree.
    pub fn corpus_dir(&self) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fuzz/corpus")
            .join(self.name)
    }
}
