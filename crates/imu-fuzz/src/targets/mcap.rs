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
    use crate::targets::files::{split_cut, with_cut};

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

    #[test]
    fn a_cut_inside_a_chunk_whose_crc_disagrees_reads_on_where_the_whole_file_stops() {
        // Found by the long run: the whole file's read delivers none of a chunk whose CRC
        // disagrees; a cut inside that chunk removes what the CRC was checked against, so the
        // cut file's read streams the chunk's messages up to the cut (as for a killed writer's
        // unfinished chunk). The check holds both: the whole's messages come first.
        // Uncompressed chunks of about 200 bytes, CRCs on, 40 messages.
        let mut w = mcap::WriteOptions::new()
            .compression(None)
            .chunk_size(Some(200))
            .create(std::io::Cursor::new(Vec::new()))
            .unwrap();
        let ch = w
            .add_channel(0, "/imu", "json", &Default::default())
            .unwrap();
        for k in 0..40u32 {
            let header = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: k,
                log_time: u64::from(k),
                publish_time: u64::from(k),
            };
            w.write_to_known_channel(&header, format!("{{\"k\":{k}}}").as_bytes())
                .unwrap();
        }
        w.finish().unwrap();
        let mut file = w.into_inner().into_inner();
        // Records after the magic: opcode (1), length (8), body; the second chunk (0x06).
        let record_len = |at: usize| {
            usize::try_from(u64::from_le_bytes(file[at + 1..at + 9].try_into().unwrap())).unwrap()
        };
        let mut at = 8;
        let mut chunks = 0;
        loop {
            if file[at] == 0x06 {
                chunks += 1;
                if chunks == 2 {
                    break;
                }
            }
            at += 9 + record_len(at);
        }
        let len = record_len(at);
        // The chunk's CRC follows its start time, end time and uncompressed size.
        file[at + 9 + 24] ^= 1;
        let whole = read(&file);
        assert!(
            matches!(&whole.outcome, Ok(Some(why)) if why.contains("CRC")),
            "{:?}",
            whole.outcome
        );
        assert!(!whole.messages.is_empty());
        let cut = at + 9 + len - 1;
        let part = read(&file[..cut]);
        assert!(
            part.messages.len() > whole.messages.len(),
            "{} {}",
            part.messages.len(),
            whole.messages.len()
        );
        assert!(part.messages.starts_with(&whole.messages));
        check(&with_cut(cut, &file));
    }
}
