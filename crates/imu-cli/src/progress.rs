//! Progress bars for long reads in the command-line clients: bytes of the
//! input file read so far, on stderr, shown only when stderr is a terminal and the input is
//! large or the read has already taken a while. Scripts, tests and pipes never see one, and
//! stdout (where `--json` goes) is never touched.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use imu_analysis::input::{CsvOptions, ImuSeries, InputError, InputOptions, Source};

/// Inputs at least this large get a bar from the start, bytes.
pub const SHOW_ABOVE_BYTES: u64 = 20 * 1024 * 1024;

/// Smaller inputs get one once the read has taken this long.
pub const SHOW_AFTER: Duration = Duration::from_secs(1);

/// Whether a read should show a bar: only on a terminal, and only for a large input or a read
/// that has taken a while.
pub fn should_show(stderr_is_terminal: bool, total_bytes: u64, elapsed: Duration) -> bool {
    stderr_is_terminal && (total_bytes >= SHOW_ABOVE_BYTES || elapsed >= SHOW_AFTER)
}

/// A bytes-read bar that starts hidden and appears on stderr when [`should_show`] says so.
pub struct ReadProgress {
    bar: ProgressBar,
    start: Instant,
    stderr_is_terminal: bool,
    shown: bool,
}

impl ReadProgress {
    /// A hidden bar labelled `label` (e.g. `reading rec.mcap`).
    pub fn new(label: impl Into<String>) -> Self {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template(
                "{msg} [{bar:40}] {binary_bytes}/{binary_total_bytes} {binary_bytes_per_sec} eta {eta}",
            )
            .expect("a valid template")
            .progress_chars("=> "),
        );
        bar.set_message(label.into());
        ReadProgress {
            bar,
            start: Instant::now(),
            stderr_is_terminal: std::io::stderr().is_terminal(),
            shown: false,
        }
    }

    /// `done` of `total` bytes read.
    pub fn update(&mut self, done: u64, total: u64) {
        if !self.shown && should_show(self.stderr_is_terminal, total, self.start.elapsed()) {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
            self.shown = true;
        }
        self.bar.set_length(total);
        self.bar.set_position(done);
    }

    /// Removes the bar (if it was shown) so the tool's own output starts on a clean line.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}

/// [`imu_analysis::input::read_any`] with a bar of the bytes read (see [`should_show`]).
pub fn read_any(path: &Path, source: Source, csv: &CsvOptions) -> Result<ImuSeries, InputError> {
    let name = path
        .file_name()
        .unwrap_or(path.as_os_str())
        .to_string_lossy();
    let mut progress = ReadProgress::new(format!("reading {name}"));
    let series =
        imu_analysis::input::read_any_with_progress(path, source, csv, &mut |done, total| {
            progress.update(done, total)
        });
    progress.finish();
    series
}

/// [`imu_analysis::input::read_input`] (one file, the files of one session, a session or
/// rosbag2 directory) with a bar of the bytes read over all its files.
pub fn read_input(paths: &[PathBuf], options: &InputOptions) -> Result<ImuSeries, InputError> {
    let name = match paths {
        [one] => one
            .file_name()
            .unwrap_or(one.as_os_str())
            .to_string_lossy()
            .into_owned(),
        many => format!("{} files", many.len()),
    };
    let mut progress = ReadProgress::new(format!("reading {name}"));
    let series = imu_analysis::input::read_input(paths, options, &mut |done, total| {
        progress.update(done, total)
    });
    progress.finish();
    series
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bar_only_on_a_terminal_for_large_or_slow_reads() {
        let short = Duration::from_millis(10);
        assert!(!should_show(false, 10 * SHOW_ABOVE_BYTES, 10 * SHOW_AFTER));
        assert!(!should_show(true, 1024, short));
        assert!(should_show(true, SHOW_ABOVE_BYTES, short));
        assert!(should_show(true, 1024, SHOW_AFTER));
    }
}
