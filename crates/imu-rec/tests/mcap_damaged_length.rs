//! A damaged length field costs a small file little memory: the tolerant MCAP reader once
//! zero-filled the whole claimed record (up to its 1 GiB limit) before finding the file's end,
//! found by the `mcap` fuzz target. Its own test binary, so the process's peak resident memory
//! (`VmHWM`) is this read's alone.

use imu_rec::mcap_read::for_each_message;

fn peak_rss_kib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

#[test]
fn a_record_claiming_half_a_gibibyte_in_a_small_file_is_named_without_allocating_it() {
    let mut file = mcap::MAGIC.to_vec();
    // Header record: empty profile and library.
    file.push(0x01);
    file.extend_from_slice(&8u64.to_le_bytes());
    file.extend_from_slice(&[0; 8]);
    // A schema record whose length says 512 MiB, in a file of 60 bytes.
    file.push(0x03);
    file.extend_from_slice(&(512u64 << 20).to_le_bytes());
    file.extend_from_slice(&[7; 24]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("damaged.mcap");
    std::fs::write(&path, &file).unwrap();

    let before_kib = peak_rss_kib();
    let report = for_each_message(&path, |_, _, _| Ok(())).unwrap();
    let grown_kib = peak_rss_kib().saturating_sub(before_kib);
    assert_eq!(report.n_messages, 0);
    let unfinished = report.unfinished.expect("the cut record is named");
    assert!(unfinished.footer_missing, "{unfinished:?}");
    assert!(grown_kib < 64 * 1024, "peak memory grew {grown_kib} KiB");
}
