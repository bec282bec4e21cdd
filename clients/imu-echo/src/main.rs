//! imu-echo: print the samples a running imud publishes over iceoryx2 shared memory.
//!
//! ```text
//! imu-echo [--name NAME] [--corrected|--raw|--status|--health] [--format table|csv|jsonl] [--count N]
//!          [--publisher-user USER] [--socket PATH]
//! ```
//!
//! It subscribes to `imud/NAME/{corrected,raw,status,health}` (corrected by default), sleeps on the
//! instance's event service until the daemon announces new samples, and prints them to stdout:
//! `table` as aligned columns with units in the header, `csv` with a header row (full
//! precision, times in ns), `jsonl` as one JSON object per line with the field names of the
//! shared-memory types (which carry their units, e.g. `accel_m_s2`). Once a second it reports
//! the receive rate and the samples missed (gaps in `seq`) on stderr.
//!
//! Before printing anything, and again before every batch, it checks that the service was created
//! by and is published by a trusted user (`--publisher-user`, repeatable; by default root, its own
//! user and the user `imud`): iceoryx2 does not say who may publish, so a process of another user
//! that created the services is refused rather than echoed.
//!
//! With `--socket PATH` it reads imud's readers' socket instead (`[publish] readers-socket`,
//! `/run/imud/NAME/readers.sock` by default): the way a process of another user in the daemon's
//! readers' group gets the streams, since iceoryx2's segments are the daemon user's alone. It
//! checks the server's user with `SO_PEERCRED` against the same trusted users, and reports the
//! packets the daemon could not queue for it besides the `seq` gaps.
//!
//! It may start before the daemon (it waits `--timeout-s` for it). Exit codes: 0 after
//! `--count` samples or when stdout is closed (`| head`), 130 on SIGINT/SIGTERM, 64 on a bad
//! command line, 1 on other errors (the codes every imud tool shares, `imu-cli`).

mod format;

use std::io::{self, BufWriter, Write};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::{ArgGroup, Parser, ValueEnum};
use imu_bus::readers::{ReadersClient, WireRecord};
use imu_bus::shm::{Stream, Subscriber, Subscription, TrustedPublishers, UserId};

use crate::format::Echo;

/// Print the samples a running imud publishes over shared memory.
#[derive(Debug, Parser)]
#[command(version, about, group(ArgGroup::new("stream").args(["corrected", "raw", "status", "health"])))]
struct Args {
    /// Instance name of the daemon (its `--name`).
    #[arg(long, default_value = imu_bus::shm::DEFAULT_INSTANCE)]
    name: String,
    /// Corrected samples in SI units (the default).
    #[arg(long)]
    corrected: bool,
    /// Raw samples: device counts and timestamps.
    #[arg(long)]
    raw: bool,
    /// The daemon's health counters (about once a second).
    #[arg(long)]
    status: bool,
    /// The live calibration health: one report per still window (states ok, degraded, stale,
    /// uncalibrated; the residuals against gravity and Earth's rate; the bias offsets that
    /// would explain them).
    #[arg(long)]
    health: bool,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    format: Format,
    /// Exit (with 0) after printing N samples.
    #[arg(long, value_name = "N")]
    count: Option<u64>,
    /// Seconds to wait for the daemon's services to appear.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0, value_parser = imu_cli::finite_f64)]
    timeout_s: f64,
    /// A user (name or uid) whose imud this client trusts; repeat for several. Default: root,
    /// this client's own user and the user `imud`.
    #[arg(long, value_name = "USER")]
    publisher_user: Vec<String>,
    /// Read imud's readers' socket at PATH (e.g. /run/imud/NAME/readers.sock) instead of
    /// shared memory: for processes of other users in the daemon's `[publish] group`.
    #[arg(long, value_name = "PATH")]
    socket: Option<std::path::PathBuf>,
    /// Do not print rate and drop statistics on stderr.
    #[arg(long, short)]
    quiet: bool,
}

/// Output formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Format {
    /// Aligned columns with units in the header.
    Table,
    /// Comma-separated values with a header row.
    Csv,
    /// One JSON object per line.
    Jsonl,
}

/// How a run ended without an error.
#[derive(Debug, PartialEq, Eq)]
enum Outcome {
    /// `--count` samples were printed.
    Done,
    /// SIGINT or SIGTERM.
    Interrupted,
}

fn main() -> ExitCode {
    imu_cli::main("imu-echo", |args: Args| {
        Ok(match run(&args)? {
            Outcome::Done => ExitCode::SUCCESS,
            Outcome::Interrupted => ExitCode::from(130),
        })
    })
}

fn run(args: &Args) -> Result<Outcome> {
    // iceoryx2 logs to stderr; keep it to errors unless IOX2_LOG_LEVEL asks for more.
    imu_bus::shm::quiet_iceoryx2_logs();

    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .context("installing the SIGINT/SIGTERM handler")?;
    }

    let stream = if args.raw {
        Stream::Raw
    } else if args.status {
        Stream::Status
    } else if args.health {
        Stream::Health
    } else {
        Stream::Corrected
    };
    let timeout = Duration::try_from_secs_f64(args.timeout_s)
        .with_context(|| format!("--timeout-s {} is not a duration", args.timeout_s))?;
    if let Some(path) = &args.socket {
        let trusted = trusted_publishers(&args.publisher_user)?;
        let client = ReadersClient::connect(path, &trusted, timeout)
            .with_context(|| format!("reading the {stream} stream from imud's readers' socket"))?;
        return match stream {
            Stream::Raw => echo_socket::<imu_bus::RawSample>(client, args, &stop),
            Stream::Corrected => echo_socket::<imu_bus::CorrectedSample>(client, args, &stop),
            Stream::Status => echo_socket::<imu_bus::DaemonStatus>(client, args, &stop),
            Stream::Health => echo_socket::<imu_bus::CalibrationHealth>(client, args, &stop),
        };
    }
    let subscriber = Subscriber::open(&args.name, stream, timeout).with_context(|| {
        format!(
            "subscribing to the {stream} stream of imud instance {:?}",
            args.name
        )
    })?;
    let trusted = trusted_publishers(&args.publisher_user)?;
    subscriber
        .verify_publisher(&trusted)
        .context("checking who publishes")?;
    match subscriber {
        Subscriber::Raw(sub) => echo(sub, args, &trusted, &stop),
        Subscriber::Corrected(sub) => echo(sub, args, &trusted, &stop),
        Subscriber::Status(sub) => echo(sub, args, &trusted, &stop),
        Subscriber::Health(sub) => echo(sub, args, &trusted, &stop),
    }
}

/// The users of `--publisher-user` (names or uids), or the default set.
fn trusted_publishers(users: &[String]) -> Result<TrustedPublishers> {
    if users.is_empty() {
        return Ok(TrustedPublishers::default_for_this_process());
    }
    let ids = users
        .iter()
        .map(|u| {
            u.parse::<u32>()
                .ok()
                .map(UserId)
                .or_else(|| UserId::by_name(u))
                .with_context(|| format!("--publisher-user {u}: no such user on this system"))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(TrustedPublishers::users(ids))
}

/// How long one wait on the listener lasts at most: bounds how late a signal is noticed and
/// when the statistics line is printed.
const WAIT_SLICE: Duration = Duration::from_millis(200);

fn echo<T: Echo>(
    mut sub: Subscription<T>,
    args: &Args,
    trusted: &TrustedPublishers,
    stop: &AtomicBool,
) -> Result<Outcome> {
    let mut out = BufWriter::new(io::stdout().lock());
    let mut stats = Stats::new(sub.service_name(), T::HAS_SEQ, args.quiet);
    let mut printer = format::Printer::<T>::new(args.format);
    printer.header(&mut out).context("writing to stdout")?;
    let mut printed = 0u64;
    if args.count == Some(0) {
        out.flush().context("writing to stdout")?;
        return Ok(Outcome::Done);
    }
    let mut batch = Vec::with_capacity(256);
    loop {
        if stop.load(Ordering::Relaxed) {
            out.flush().context("writing to stdout")?;
            stats.report(&sub, true);
            return Ok(Outcome::Interrupted);
        }
        batch.clear();
        sub.wait_into(WAIT_SLICE, &mut batch)
            .context("receiving samples")?;
        if !batch.is_empty() {
            // The publisher may have changed since the last batch (a restart).
            sub.verify_publisher(trusted)
                .context("checking who publishes")?;
        }
        for sample in &batch {
            printer.row(&mut out, sample).context("writing to stdout")?;
            printed += 1;
            if args.count == Some(printed) {
                out.flush().context("writing to stdout")?;
                stats.report(&sub, true);
                return Ok(Outcome::Done);
            }
        }
        out.flush().context("writing to stdout")?;
        stats.tick(&sub);
    }
}

/// [`echo`] for the readers' socket: the records of `T`'s stream, the others skipped.
fn echo_socket<T: Echo + WireRecord>(
    mut client: ReadersClient,
    args: &Args,
    stop: &AtomicBool,
) -> Result<Outcome> {
    let mut out = BufWriter::new(io::stdout().lock());
    let mut printer = format::Printer::<T>::new(args.format);
    printer.header(&mut out).context("writing to stdout")?;
    let mut printed = 0u64;
    let started = Instant::now();
    let mut last_report = started;
    let report = |client: &ReadersClient, printed: u64, last: bool| {
        if args.quiet {
            return;
        }
        eprintln!(
            "imu-echo: {}{}: {printed} printed in {:.1} s, {} missed (seq gaps), {} packets the \
             daemon could not queue for this reader",
            client.path().display(),
            if last { "" } else { " (running)" },
            started.elapsed().as_secs_f64(),
            client.missed(),
            client.server_dropped()
        );
    };
    while args.count != Some(printed) {
        if stop.load(Ordering::Relaxed) {
            out.flush().context("writing to stdout")?;
            report(&client, printed, true);
            return Ok(Outcome::Interrupted);
        }
        if let Some(record) = client.recv(WAIT_SLICE).context("receiving samples")?
            && let Some(sample) = T::take(record)
        {
            printer
                .row(&mut out, &sample)
                .context("writing to stdout")?;
            printed += 1;
        }
        if last_report.elapsed() >= Stats::PERIOD {
            out.flush().context("writing to stdout")?;
            report(&client, printed, false);
            last_report = Instant::now();
        }
    }
    out.flush().context("writing to stdout")?;
    report(&client, printed, true);
    Ok(Outcome::Done)
}

/// The once-a-second rate and drop report on stderr.
struct Stats {
    service: String,
    has_seq: bool,
    quiet: bool,
    started: Instant,
    last_report: Instant,
    received_at_last_report: u64,
}

impl Stats {
    const PERIOD: Duration = Duration::from_secs(1);

    fn new(service: &str, has_seq: bool, quiet: bool) -> Stats {
        let now = Instant::now();
        Stats {
            service: service.to_owned(),
            has_seq,
            quiet,
            started: now,
            last_report: now,
            received_at_last_report: 0,
        }
    }

    fn tick<T: Echo>(&mut self, sub: &Subscription<T>) {
        if self.last_report.elapsed() >= Self::PERIOD {
            self.report(sub, false);
        }
    }

    fn report<T: Echo>(&mut self, sub: &Subscription<T>, last: bool) {
        let now = Instant::now();
        let window_s = now.duration_since(self.last_report).as_secs_f64();
        let received = sub.received();
        let rate_hz = (received - self.received_at_last_report) as f64 / window_s.max(1e-9);
        self.last_report = now;
        self.received_at_last_report = received;
        if self.quiet {
            return;
        }
        let missed = if self.has_seq {
            let missed = sub.missed();
            let total = received + missed;
            let pct = if total > 0 {
                100.0 * missed as f64 / total as f64
            } else {
                0.0
            };
            format!("{missed} missed ({pct:.2} %, seq gaps)")
        } else {
            "missed n/a (no seq)".to_owned()
        };
        let publisher = if sub.publishers() == 0 {
            ", no publisher: is imud running?"
        } else {
            ""
        };
        if last {
            let elapsed_s = now.duration_since(self.started).as_secs_f64();
            eprintln!(
                "imu-echo: {}: {received} received in {elapsed_s:.1} s, {missed}",
                self.service
            );
        } else {
            eprintln!(
                "imu-echo: {}: {rate_hz:.1} samples/s, {received} received, {missed}{publisher}",
                self.service
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        Args::command().debug_assert();
    }

    #[test]
    fn stream_flags_are_exclusive() {
        assert!(Args::try_parse_from(["imu-echo", "--raw", "--status"]).is_err());
        let args = Args::try_parse_from(["imu-echo", "--raw", "--format", "csv", "--count", "3"])
            .expect("valid");
        assert!(args.raw);
        assert_eq!(args.format, Format::Csv);
        assert_eq!(args.count, Some(3));
        assert_eq!(args.name, "default");
    }

    #[test]
    fn a_broken_pipe_is_recognised_through_context() {
        let e = anyhow::Error::from(io::Error::from(io::ErrorKind::BrokenPipe))
            .context("writing to stdout");
        assert!(imu_cli::is_broken_pipe(e.chain()));
        assert!(!imu_cli::is_broken_pipe(anyhow::anyhow!("other").chain()));
    }
}
