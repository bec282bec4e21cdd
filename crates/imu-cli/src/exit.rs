//! The one `main` of every imud tool: parse the command line, run, print the error chain once,
//! and map it to a sysexits-style exit code the same way for every client and the daemon.
//!
//! | code | meaning                                                          |
//! |------|------------------------------------------------------------------|
//! | 0    | success, `--help`/`--version`, or a reader that closed our pipe  |
//! | 64   | usage: a bad flag or value (`EX_USAGE`)                          |
//! | 65   | an input was read but its data are unusable (`EX_DATAERR`)       |
//! | 66   | an input file cannot be opened (`EX_NOINPUT`)                    |
//! | 1    | anything else                                                    |

use std::ffi::OsString;
use std::process::ExitCode;

use clap::{ArgMatches, CommandFactory, FromArgMatches};
use imu_rec::McapReadError;

/// `EX_USAGE`: the command line is wrong.
pub const EXIT_USAGE: u8 = 64;
/// `EX_DATAERR`: an input was read but its data are unusable.
pub const EXIT_DATA: u8 = 65;
/// `EX_NOINPUT`: an input file does not exist or cannot be read.
pub const EXIT_NO_INPUT: u8 = 66;

/// Marks an error as a usage error (exit 64) when clap could not say so itself, e.g. two flags
/// whose counts do not match.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

impl UsageError {
    /// clap's error, as one line without clap's own `error: ` prefix.
    pub fn from_clap(e: clap::Error) -> Self {
        let text = e.to_string();
        let first = text.lines().next().unwrap_or_default();
        UsageError(first.trim_start_matches("error: ").to_string())
    }
}

/// Marks an error as unusable input data (exit 65) when its type does not say so already.
#[derive(Debug)]
pub struct DataError(pub String);

impl std::fmt::Display for DataError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DataError {}

/// What a tool's `run` may return: nothing (exit 0) or its own exit code (e.g. 130 after
/// SIGINT).
pub trait Outcome {
    /// The process exit code.
    fn exit_code(self) -> ExitCode;
}

impl Outcome for () {
    fn exit_code(self) -> ExitCode {
        ExitCode::SUCCESS
    }
}

impl Outcome for ExitCode {
    fn exit_code(self) -> ExitCode {
        self
    }
}

/// The exit code of a failed run (see the module table). The first cause that says something
/// decides: the outermost error is the most specific.
pub fn exit_code_of(e: &anyhow::Error) -> u8 {
    for cause in e.chain() {
        if let Some(code) = classify(cause) {
            return code;
        }
    }
    1
}

fn classify(cause: &(dyn std::error::Error + 'static)) -> Option<u8> {
    if cause.is::<UsageError>() || cause.is::<clap::Error>() {
        return Some(EXIT_USAGE);
    }
    if cause.is::<DataError>() {
        return Some(EXIT_DATA);
    }
    let mcap = |e: &McapReadError| match e {
        McapReadError::Io { .. } => EXIT_NO_INPUT,
        _ => EXIT_DATA,
    };
    if let Some(e) = cause.downcast_ref::<McapReadError>() {
        return Some(mcap(e));
    }
    #[cfg(feature = "analysis")]
    if let Some(code) = classify_analysis(cause, mcap) {
        return Some(code);
    }
    // Any other file that does not exist or may not be read (a model, a plan, a config file).
    if let Some(io) = cause.downcast_ref::<std::io::Error>()
        && matches!(
            io.kind(),
            std::io::ErrorKind::NotFound | std::io::ErrorKind::PermissionDenied
        )
    {
        return Some(EXIT_NO_INPUT);
    }
    None
}

/// The offline clients' input and analysis errors.
#[cfg(feature = "analysis")]
fn classify_analysis(
    cause: &(dyn std::error::Error + 'static),
    mcap: impl Fn(&McapReadError) -> u8,
) -> Option<u8> {
    use imu_analysis::InputError;
    use imu_analysis::characterize::{dynamic, impact, thermal};
    if let Some(e) = cause.downcast_ref::<InputError>() {
        return Some(match e {
            InputError::Io { .. } => EXIT_NO_INPUT,
            // Transparent: its source() skips the MCAP error, so look inside here.
            InputError::Mcap(m) => mcap(m),
            _ => EXIT_DATA,
        });
    }
    if cause.is::<thermal::ThermalError>()
        || cause.is::<impact::ImpactError>()
        || cause.is::<dynamic::DynamicError>()
    {
        return Some(EXIT_DATA);
    }
    None
}

/// Prints a failed run's error chain once (`NAME: error: a: b: c`) and returns its exit code;
/// a closed output pipe is no failure (exit 0, nothing printed).
pub fn report(name: &str, e: &anyhow::Error) -> ExitCode {
    if crate::args::is_broken_pipe(e.chain()) {
        return ExitCode::SUCCESS;
    }
    eprintln!("{name}: error: {e:#}");
    ExitCode::from(exit_code_of(e))
}

/// Parses `args` with `C`'s clap command: help and version print and exit 0, a usage error
/// prints clap's message and exits 64.
pub fn matches_from<C: CommandFactory>(
    args: impl IntoIterator<Item = OsString>,
) -> Result<ArgMatches, ExitCode> {
    C::command().try_get_matches_from(args).map_err(|e| {
        let _ = e.print();
        if e.use_stderr() {
            ExitCode::from(EXIT_USAGE)
        } else {
            ExitCode::SUCCESS
        }
    })
}

/// The `main` of a tool whose command line is the clap type `C`: handles the hidden
/// `--generate man|bash|zsh|fish|elvish|powershell DIR` (see [`crate::generate`]), parses,
/// runs, and reports errors with the exit codes of the module table. `name` prefixes errors.
pub fn main<C, T>(name: &str, run: impl FnOnce(C) -> anyhow::Result<T>) -> ExitCode
where
    C: CommandFactory + FromArgMatches,
    T: Outcome,
{
    main_with_matches::<C, T>(name, |m| {
        let cli = C::from_arg_matches(m).map_err(UsageError::from_clap)?;
        run(cli)
    })
}

/// [`main`] for a tool that needs clap's [`ArgMatches`] itself (e.g. to see the order of
/// repeated flags).
pub fn main_with_matches<C, T>(
    name: &str,
    run: impl FnOnce(&ArgMatches) -> anyhow::Result<T>,
) -> ExitCode
where
    C: CommandFactory,
    T: Outcome,
{
    let args: Vec<OsString> = std::env::args_os().collect();
    if let Some(code) = crate::generate::handle::<C>(&args) {
        return code;
    }
    let matches = match matches_from::<C>(args) {
        Ok(m) => m,
        Err(code) => return code,
    };
    match run(&matches) {
        Ok(outcome) => outcome.exit_code(),
        Err(e) => report(name, &e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[cfg(feature = "analysis")]
    #[test]
    fn the_same_failure_has_the_same_code_in_every_tool() {
        use imu_analysis::InputError;
        let missing = || std::io::Error::from(std::io::ErrorKind::NotFound);
        let mcap = anyhow::Error::new(InputError::Mcap(McapReadError::Io {
            path: PathBuf::from("rec.mcap"),
            source: missing(),
        }))
        .context("reading rec.mcap");
        assert_eq!(exit_code_of(&mcap), EXIT_NO_INPUT);
        let csv = anyhow::Error::new(InputError::Io {
            path: PathBuf::from("rec.csv"),
            source: missing(),
        });
        assert_eq!(exit_code_of(&csv), EXIT_NO_INPUT);
        let not_mcap = anyhow::Error::new(InputError::Mcap(McapReadError::NotMcap {
            path: PathBuf::from("x.mcap"),
            message: "bad magic".into(),
        }));
        assert_eq!(exit_code_of(&not_mcap), EXIT_DATA);
        let empty = anyhow::Error::new(InputError::NoData {
            path: PathBuf::from("x.mcap"),
            message: "no IMU messages".into(),
        });
        assert_eq!(exit_code_of(&empty), EXIT_DATA);
        let usage = anyhow::Error::new(UsageError("2 --gyro-csv for 1 CSV".into()));
        assert_eq!(exit_code_of(&usage.context("options")), EXIT_USAGE);
        let model = anyhow::Error::new(missing()).context("reading model.toml");
        assert_eq!(exit_code_of(&model), EXIT_NO_INPUT);
        assert_eq!(exit_code_of(&anyhow::anyhow!("fit diverged")), 1);
    }

    #[derive(Debug, clap::Parser)]
    struct Demo {
        #[arg(long, value_parser = crate::finite_f64)]
        scale_s: f64,
    }

    #[test]
    fn usage_errors_exit_64_and_help_exits_0() {
        let os = |v: &[&str]| v.iter().map(OsString::from).collect::<Vec<_>>();
        assert!(matches_from::<Demo>(os(&["demo", "--scale-s", "2"])).is_ok());
        let nan = matches_from::<Demo>(os(&["demo", "--scale-s", "nan"])).unwrap_err();
        assert_eq!(nan, ExitCode::from(EXIT_USAGE));
        let help = matches_from::<Demo>(os(&["demo", "--help"])).unwrap_err();
        assert_eq!(help, ExitCode::SUCCESS);
    }
}
