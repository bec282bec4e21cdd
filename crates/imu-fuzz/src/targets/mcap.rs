//! The tolerant MCAP reader (`imu_rec::mcap_read`): see `files` for the checks; its report
//! agrees with what it handed over, and `Unfinished` is set exactly when the read stopped early.

use super::files::{Message, Read, check_cut, through_file};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "mcap",
    about: "the tolerant MCAP reader (imu_rec::mcap_read), whole and cut files",
    check,
    seeds: Some(crate::seeds::mcap),
    dictionary: &[
        b"\x89MCAP0\r\n",
        &[0x01],
        &[0x02],
        &[0x03],
        &[0x04],
        &[0x05],
        &[0x06],
        &[0x0F],
        &[0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00],
        &[0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x7F],
        b"zstd",
        b"lz4",
    ],
    ci_mutations: 20_000,
};

/// Input: `[cut (u16, little-endian), file...]`.
fn check(data: &[u8]) {
    check_cut(data, read);
}

/// Reads an MCAP file's bytes.
pub(crate) fn read(file: &[u8]) -> Read {
    through_file("input.mcap", file, |path| {
        let mut messages = Vec::new();
        let outcome = imu_rec::mcap_read::for_each_message(path, |channel, header, data| {
            messages.push(Message {
                topic: channel.topic.clone(),
                msg_type: channel.schema_name.clone(),
                time_ns: header.log_time,
                data: data.to_vec(),
            });
            Ok(())
        });
        if let Ok(report) = &outcome
            && let Some(u) = &report.unfinished
        {
            assert_eq!(u.n_messages, report.n_messages, "Unfinished counts");
        }
        let outcome = outcome.map(|r| (r.n_messages, r.stopped_early, r.unfinished.is_some()));
        let outcome = super::files::outcome(outcome, messages.len());
        Read { messages, outcome }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::targets::files::split_cut;

    #[test]
    fn a_whole_truth_file_reads_completely_and_its_cuts_are_named() {
        // The seeds: truth files of 0, 3 and 12 samples (plus one segment each), whole, cut by
        // one byte, cut in half and cut 40 bytes short.
        let seeds = crate::seeds::mcap();
        let whole: Vec<Read> = seeds
            .iter()
            .step_by(4)
            .map(|s| read(split_cut(s).unwrap().1))
            .collect();
        let counts: Vec<usize> = whole.iter().map(|r| r.messages.len()).collect();
        assert_eq!(counts, [1, 4, 13]);
        assert!(whole.iter().all(|r| r.outcome == Ok(None)));
        assert_eq!(whole[2].messages[5].topic, "/truth/sample");
        for seed in &seeds {
            let (cut, file) = split_cut(seed).unwrap();
            if cut < file.len() {
                let part = read(&file[..cut]);
                assert!(part.outcome.is_err() || matches!(part.outcome, Ok(Some(_))));
            }
            check(seed);
        }
    }
}
