//! What every imud command-line tool shares, so the five clients and the daemon behave alike:
//!
//! - [`args`]: the CSV arguments every offline client flattens (`CsvArgs`, feature `analysis`), the `--add EFFECT`
//!   parser, [`finite_f64`] (the value parser of every float flag: NaN and infinities are
//!   usage errors), the broken-pipe check;
//! - `progress` (feature `analysis`, on by default; the daemon goes without it): the bytes-read
//!   progress bar of long reads (stderr, terminals only), over all the files of a session;
//! - [`exit`]: the one `main` ([`main`], [`main_with_matches`]) that prints an error chain once and
//!   maps it to a sysexits-style code (64 usage, 65 unusable data, 66 cannot open an input, 1
//!   otherwise; a closed output pipe exits 0);
//! - [`generate`]: man pages and shell completions from the clap command (`--generate`), used
//!   by `scripts/install`;
//! - [`unfinished`]: the one-line warning for an MCAP input read without its footer;
//! - `session` (feature `analysis`): the warnings about a recording read (unfinished file, gaps
//!   between the files of a session).

pub mod args;
pub mod exit;
pub mod generate;
#[cfg(feature = "analysis")]
pub mod progress;
#[cfg(feature = "analysis")]
pub mod session;
pub mod unfinished;

#[cfg(feature = "analysis")]
pub use args::CsvArgs;
pub use args::{finite_f64, is_broken_pipe, parse_effect};
pub use exit::{DataError, Outcome, UsageError, main, main_with_matches};
