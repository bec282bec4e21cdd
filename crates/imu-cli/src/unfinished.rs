//! The warning every offline client gives when it reads an MCAP file without its footer (a
//! writer killed mid-recording): one line on stderr, and the same facts for `--json`.

use std::path::Path;
use std::time::{Duration, UNIX_EPOCH};

use imu_rec::Unfinished;

/// `YYYYMMDDTHHMMSS.mmmZ` of a Unix-epoch time in ns.
pub fn utc_ms(t_ns: u64) -> String {
    let stamp = imu_rec::recording::utc_stamp(UNIX_EPOCH + Duration::from_nanos(t_ns));
    let ms = t_ns / 1_000_000 % 1000;
    format!("{}.{ms:03}Z", stamp.trim_end_matches('Z'))
}

/// The one-line warning (without the tool's prefix).
pub fn warning(path: &Path, u: &Unfinished) -> String {
    let what = if u.footer_missing {
        "unfinished recording (no footer: its writer stopped without closing it)"
    } else {
        "damaged recording"
    };
    let until = match u.last_log_time_ns {
        Some(t) => format!("up to log time {} ({t} ns)", utc_ms(t)),
        None => "no message".into(),
    };
    format!(
        "{}: {what}: read {} messages, {until}; `{}` repairs it ({})",
        path.display(),
        u.n_messages,
        u.repair,
        u.reason
    )
}

/// The same facts for a `--json` document: `{"path", "footer_missing", "reason",
/// "n_messages", "last_log_time_ns", "last_log_time_utc"}`.
pub fn json(path: &Path, u: &Unfinished) -> serde_json::Value {
    serde_json::json!({
        "path": path.display().to_string(),
        "footer_missing": u.footer_missing,
        "reason": u.reason,
        "n_messages": u.n_messages,
        "last_log_time_ns": u.last_log_time_ns,
        "last_log_time_utc": u.last_log_time_ns.map(utc_ms),
    })
}

/// Prints the warning for an input read without its footer as `tool: warning: ...` on stderr
/// and returns its JSON form; `None` (and silence) for a complete input.
pub fn warn(tool: &str, path: &Path, u: Option<&Unfinished>) -> Option<serde_json::Value> {
    let u = u?;
    eprintln!("{tool}: warning: {}", warning(path, u));
    Some(json(path, u))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_warning_says_up_to_when_it_read_and_how_to_repair() {
        let u = Unfinished {
            footer_missing: true,
            reason: "file ends mid-record".into(),
            n_messages: 42,
            last_log_time_ns: Some(1_700_000_000_123_456_789),
            repair: "imud recover rec.mcap".into(),
        };
        let w = warning(Path::new("rec.mcap"), &u);
        assert_eq!(
            w,
            "rec.mcap: unfinished recording (no footer: its writer stopped without closing it): \
             read 42 messages, up to log time 20231114T221320.123Z (1700000000123456789 ns); \
             `imud recover rec.mcap` repairs it (file ends mid-record)"
        );
        let j = json(Path::new("rec.mcap"), &u);
        assert_eq!(j["last_log_time_utc"], "20231114T221320.123Z");
        assert_eq!(j["footer_missing"], true);
        assert_eq!(warn("t", Path::new("x"), None), None);
    }
}
