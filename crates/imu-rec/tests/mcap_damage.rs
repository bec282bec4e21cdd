//! The tolerant MCAP reader on hand-built files: chunks in each compression MCAP writers use
//! (none, zstd, lz4), and the damage fuzzing found or a killed writer leaves: a record inside a
//! chunk claiming more than the chunk holds, a chunk cut by the end of the file, a wrong chunk
//! CRC. Every message before the damage is delivered, in order, and the damage is named.

use imu_rec::mcap_read::{ReadReport, for_each_message};

fn string(s: &str) -> Vec<u8> {
    let mut out = (s.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(s.as_bytes());
    out
}

fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut out = vec![opcode];
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    out.extend_from_slice(body);
    out
}

fn header() -> Vec<u8> {
    record(0x01, &[string("test"), string("hand-built")].concat())
}

/// Channel 1 on `/imu`, no schema, JSON messages.
fn channel() -> Vec<u8> {
    let mut body = 1u16.to_le_bytes().to_vec();
    body.extend_from_slice(&0u16.to_le_bytes());
    body.extend_from_slice(&string("/imu"));
    body.extend_from_slice(&string("json"));
    body.extend_from_slice(&0u32.to_le_bytes());
    record(0x04, &body)
}

/// Message `k` on channel 1, logged at `k` ms.
fn message(k: u32) -> Vec<u8> {
    let mut body = 1u16.to_le_bytes().to_vec();
    body.extend_from_slice(&k.to_le_bytes());
    body.extend_from_slice(&(u64::from(k) * 1_000_000).to_le_bytes());
    body.extend_from_slice(&(u64::from(k) * 1_000_000).to_le_bytes());
    body.extend_from_slice(format!("{{\"k\":{k}}}").as_bytes());
    record(0x05, &body)
}

#[derive(Clone, Copy)]
enum Compression {
    None,
    Zstd,
    Lz4,
}

/// A chunk of `records` (already framed), its CRC right unless `crc` overrides it.
fn chunk(records: &[u8], compression: Compression, crc: Option<u32>) -> Vec<u8> {
    let (name, compressed) = match compression {
        Compression::None => ("", records.to_vec()),
        Compression::Zstd => ("zstd", zstd::bulk::compress(records, 3).unwrap()),
        Compression::Lz4 => {
            use std::io::Write;
            // 64 KiB blocks, lz4's default (Python `lz4.frame`, the Go and C++ writers).
            let info =
                lz4_flex::frame::FrameInfo::new().block_size(lz4_flex::frame::BlockSize::Max64KB);
            let mut enc = lz4_flex::frame::FrameEncoder::with_frame_info(info, Vec::new());
            enc.write_all(records).unwrap();
            ("lz4", enc.finish().unwrap())
        }
    };
    let mut body = 0u64.to_le_bytes().to_vec();
    body.extend_from_slice(&0u64.to_le_bytes());
    body.extend_from_slice(&(records.len() as u64).to_le_bytes());
    let crc = crc.unwrap_or_else(|| crc32fast::hash(records));
    body.extend_from_slice(&crc.to_le_bytes());
    body.extend_from_slice(&string(name));
    body.extend_from_slice(&(compressed.len() as u64).to_le_bytes());
    body.extend_from_slice(&compressed);
    record(0x06, &body)
}

fn finish(file: &mut Vec<u8>) {
    file.extend_from_slice(&record(0x0F, &0u32.to_le_bytes()));
    file.extend_from_slice(&record(0x02, &[0u8; 20]));
    file.extend_from_slice(mcap::MAGIC);
}

/// The channel and messages `0..n`, framed, as a chunk's records.
fn records(n: u32) -> Vec<u8> {
    let mut out = channel();
    for k in 0..n {
        out.extend_from_slice(&message(k));
    }
    out
}

/// Reads `file`, returning the sequence numbers delivered and the report.
fn read(file: &[u8]) -> (Vec<u32>, ReadReport) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hand.mcap");
    std::fs::write(&path, file).unwrap();
    let mut seqs = Vec::new();
    let report = for_each_message(&path, |ch, header, data| {
        assert_eq!(ch.topic, "/imu");
        assert_eq!(data, format!("{{\"k\":{}}}", header.sequence).as_bytes());
        seqs.push(header.sequence);
        Ok(())
    })
    .unwrap();
    (seqs, report)
}

#[test]
fn chunks_in_every_compression_read_completely() {
    for compression in [Compression::None, Compression::Zstd, Compression::Lz4] {
        let mut file = mcap::MAGIC.to_vec();
        file.extend_from_slice(&header());
        file.extend_from_slice(&chunk(&records(50), compression, None));
        // A second chunk, and an empty one between.
        file.extend_from_slice(&chunk(&[], compression, None));
        let more: Vec<u8> = (50..80).flat_map(message).collect();
        file.extend_from_slice(&chunk(&more, compression, None));
        finish(&mut file);
        let (seqs, report) = read(&file);
        assert_eq!(seqs, (0..80).collect::<Vec<_>>());
        assert_eq!(report.stopped_early, None);
        assert_eq!(report.unfinished, None);
    }
}

#[test]
fn a_record_claiming_more_than_its_uncompressed_chunk_holds_ends_the_read_there() {
    // What the `mcap` fuzz target found: the crate's reader overflowed here.
    let mut inner = records(5);
    let mut bad = message(5);
    bad[1..9].copy_from_slice(&(u64::MAX - 3).to_le_bytes());
    inner.extend_from_slice(&bad);
    inner.extend_from_slice(&message(6));
    let mut file = mcap::MAGIC.to_vec();
    file.extend_from_slice(&header());
    file.extend_from_slice(&chunk(&inner, Compression::None, Some(0)));
    finish(&mut file);
    let (seqs, report) = read(&file);
    assert_eq!(seqs, [0, 1, 2, 3, 4]);
    let reason = report.stopped_early.expect("the damage is named");
    assert!(reason.contains("damaged chunk"), "{reason}");
    let unfinished = report.unfinished.expect("and reported as data");
    assert_eq!(unfinished.n_messages, 5);
    assert_eq!(unfinished.last_log_time_ns, Some(4_000_000));
}

#[test]
fn a_chunk_cut_by_the_end_of_the_file_yields_its_records_before_the_cut() {
    for compression in [Compression::None, Compression::Zstd, Compression::Lz4] {
        let mut file = mcap::MAGIC.to_vec();
        file.extend_from_slice(&header());
        // About 0.9 MB of records, as a writer's chunk holds: zstd and lz4 decode a block (up to
        // 128 KiB, 64 KiB) only whole, so a cut loses at most its last block.
        file.extend_from_slice(&chunk(&records(20_000), compression, None));
        let whole = file.len();
        let mut n_seen = Vec::new();
        for keep in [whole - 1, whole * 3 / 4, whole / 2] {
            let (seqs, report) = read(&file[..keep]);
            assert_eq!(seqs, (0..seqs.len() as u32).collect::<Vec<_>>());
            let unfinished = report.unfinished.expect("the cut is named");
            assert!(unfinished.footer_missing, "{unfinished:?}");
            assert!(
                unfinished.reason.contains("not closed cleanly"),
                "{unfinished:?}"
            );
            n_seen.push(seqs.len());
        }
        // Streamed decompression delivers most of a cut chunk, the more the later the cut.
        assert!(n_seen[0] >= 18_000, "{n_seen:?}");
        assert!(
            n_seen[0] >= n_seen[1] && n_seen[1] >= n_seen[2],
            "{n_seen:?}"
        );
        assert!(n_seen[2] >= 8_000, "{n_seen:?}");
    }
}

/// Three chunks (messages 0..10, 10..3000, 3000..3010), the second passed through `damage`
/// after it is built.
fn three_chunks(damage: impl Fn(&mut Vec<u8>)) -> Vec<u8> {
    let mut file = mcap::MAGIC.to_vec();
    file.extend_from_slice(&header());
    file.extend_from_slice(&chunk(&records(10), Compression::Zstd, None));
    let second: Vec<u8> = (10..3000).flat_map(message).collect();
    let mut second = chunk(&second, Compression::Zstd, None);
    damage(&mut second);
    file.extend_from_slice(&second);
    let third: Vec<u8> = (3000..3010).flat_map(message).collect();
    file.extend_from_slice(&chunk(&third, Compression::Zstd, None));
    finish(&mut file);
    file
}

#[test]
fn a_chunk_whose_crc_disagrees_delivers_none_of_its_records() {
    // The CRC field follows the record prefix (9 bytes) and three u64 fields.
    let file = three_chunks(|c| c[9 + 24] ^= 1);
    let (seqs, report) = read(&file);
    assert_eq!(seqs, (0..10).collect::<Vec<_>>());
    let reason = report.stopped_early.expect("the CRC is named");
    assert!(reason.contains("CRC"), "{reason}");
    assert!(!report.unfinished.unwrap().footer_missing);
}

#[test]
fn damaged_compressed_bytes_deliver_no_garbage() {
    // zstd as written here has no checksum of its own: flipped bytes decode to other bytes, or
    // fail to decode; either way the chunk's CRC catches it before any of its messages is
    // delivered (`read` checks every message's content against its sequence number).
    for offset in [80, 400, 2000] {
        let file = three_chunks(|c| {
            for b in &mut c[offset..offset + 8] {
                *b ^= 0x5A;
            }
        });
        let (seqs, report) = read(&file);
        assert_eq!(seqs, (0..10).collect::<Vec<_>>(), "damage at {offset}");
        let reason = report.stopped_early.expect("the damage is named");
        assert!(reason.contains("damaged chunk"), "{reason}");
    }
}

#[test]
fn a_file_without_the_magic_is_not_mcap() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("text.mcap");
    std::fs::write(&path, b"time,ax,ay,az\n0,0,0,9.8\n").unwrap();
    let err = for_each_message(&path, |_, _, _| Ok(())).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("not an MCAP file") && text.contains("text.mcap"),
        "{text}"
    );
}

#[test]
fn an_attachment_too_short_for_its_crc_is_damage_not_a_panic() {
    // mcap 0.26's `parse_record` panicked on this (found by the `mcap` fuzz target): the read
    // skips attachments, the repair copies them and must refuse this one.
    let mut attachment = 0u64.to_le_bytes().to_vec();
    attachment.extend_from_slice(&0u64.to_le_bytes());
    attachment.extend_from_slice(&string("a"));
    attachment.extend_from_slice(&string("text/plain"));
    attachment.extend_from_slice(&0u64.to_le_bytes());
    attachment.extend_from_slice(&[0, 0]); // two of the CRC's four bytes
    let mut file = mcap::MAGIC.to_vec();
    file.extend_from_slice(&header());
    file.extend_from_slice(&chunk(&records(3), Compression::None, None));
    file.extend_from_slice(&record(0x09, &attachment));
    file.extend_from_slice(&chunk(
        &[3, 4].map(message).concat(),
        Compression::None,
        None,
    ));
    // No footer: the writer was killed, so the repair runs.
    let (seqs, report) = read(&file);
    assert_eq!(seqs, [0, 1, 2, 3, 4]);
    assert!(report.unfinished.unwrap().footer_missing);

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("attached.mcap");
    std::fs::write(&path, &file).unwrap();
    let repaired = imu_rec::recover::recover(&path, false)
        .unwrap()
        .expect("repaired");
    assert_eq!(repaired.n_messages, 3, "{repaired:?}");
    assert!(repaired.reason.contains("undecodable"), "{repaired:?}");
}

#[test]
fn a_chunk_claiming_more_than_the_record_limit_uncompressed_is_damage() {
    // The uncompressed size bounds decompression: a damaged one is refused before any of the
    // chunk is expanded.
    let mut file = mcap::MAGIC.to_vec();
    file.extend_from_slice(&header());
    file.extend_from_slice(&chunk(&records(3), Compression::Zstd, None));
    let mut second = chunk(&[3, 4].map(message).concat(), Compression::Zstd, None);
    // The uncompressed size follows the record prefix (9 bytes) and two u64 times.
    second[9 + 16..9 + 24].copy_from_slice(&(1u64 << 40).to_le_bytes());
    file.extend_from_slice(&second);
    finish(&mut file);
    let (seqs, report) = read(&file);
    assert_eq!(seqs, [0, 1, 2]);
    let reason = report.stopped_early.expect("the damage is named");
    assert!(reason.contains("uncompressed bytes"), "{reason}");
}
