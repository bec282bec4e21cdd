//! The decoders' fuzz checks in one place: what every input must satisfy (no panic, every byte
//! accounted for exactly once, events that rebuild the stream), run by the coverage-guided
//! cargo-fuzz targets in `fuzz/` and by this crate's stable-Rust harness ([`run()`]), which replays
//! the committed corpus (`fuzz/corpus/<target>/`) and seeded mutations of it.
//!
//! A check panics when an invariant breaks; the harness catches the panic and reports the input.

use std::path::{Path, PathBuf};

pub mod corpus;
pub mod mutate;
pub mod run;
pub mod seeds;
mod targets;

pub use run::{Failure, RunReport, run};

/// One fuzz target: a decoder and the checks its events must pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// 3DM-GX1 replies, host side (`imu_proto::decoder::ReplyDecoder`).
    ReplyDecoder,
    /// 3DM-GX1 commands, device side (`imu_proto::decoder::CommandDecoder`).
    CommandDecoder,
    /// MIP packets, both sides (`imu_proto::mip::MipDecoder`).
    MipDecoder,
    /// VectorNav binary messages and ASCII sentences, both sides
    /// (`imu_proto::vectornav::VnDecoder`).
    VectornavDecoder,
}

impl Target {
    /// Every target, in the order reports list them.
    pub const ALL: [Target; 4] = [
        Target::ReplyDecoder,
        Target::CommandDecoder,
        Target::MipDecoder,
        Target::VectornavDecoder,
    ];

    /// The name of the cargo-fuzz binary and of the corpus directory.
    pub fn name(self) -> &'static str {
        match self {
            Target::ReplyDecoder => "reply_decoder",
            Target::CommandDecoder => "command_decoder",
            Target::MipDecoder => "mip_decoder",
            Target::VectornavDecoder => "vectornav_decoder",
        }
    }

    /// The target called `name`, if any.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Runs the target's checks on one input; panics if an invariant breaks.
    pub fn check(self, data: &[u8]) {
        match self {
            Target::ReplyDecoder => targets::reply_decoder(data),
            Target::CommandDecoder => targets::command_decoder(data),
            Target::MipDecoder => targets::mip_decoder(data),
            Target::VectornavDecoder => targets::vectornav_decoder(data),
        }
    }

    /// The committed corpus of this target: `fuzz/corpus/<name>/` in the source tree.
    pub fn corpus_dir(self) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fuzz/corpus")
            .join(self.name())
    }
}
