//! Reading an MCAP recording front to back: imu-rec's tolerant reader (`mcap_read`, its own
//! record layer) against the `mcap` crate's sans-IO `LinearReader` it replaced, on the same file
//! in the same run, both checking every chunk's CRC and handing over every message.
//!
//! The file: messages of 120 bytes (about an IMU sample's CDR) on two channels in zstd chunks of
//! 1 MiB, as imud's recorder writes them, written once per run into a temporary directory.
//!
//! Run: `cargo bench -p imu-rec --bench mcap_read` (`IMUD_BENCH_MCAP_MESSAGES` sets the message
//! count, default 2,000,000; `IMUD_BENCH_RUNS` the runs per reader, default 5). Results in
//! BENCHMARKS.md.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Read};
use std::path::Path;
use std::time::Instant;

use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Writes `n` messages alternating between two channels; returns the file's size, bytes.
fn write(path: &Path, n: usize) -> u64 {
    let out = BufWriter::new(File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(1 << 20))
        .create(out)
        .unwrap();
    let schema = w.add_schema("sensor_msgs/msg/Imu", "ros2msg", b"").unwrap();
    let channels = [
        w.add_channel(schema, "/imu/raw", "cdr", &BTreeMap::new())
            .unwrap(),
        w.add_channel(schema, "/imu/corrected", "cdr", &BTreeMap::new())
            .unwrap(),
    ];
    let mut data = [0u8; 120];
    for k in 0..n {
        // Varying payloads (a counter and a slow ramp), compressible as real samples are.
        data[..8].copy_from_slice(&(k as u64).to_le_bytes());
        data[8..16].copy_from_slice(&((k as f64) * 1e-3).sin().to_le_bytes());
        let t_ns = 1_700_000_000_000_000_000 + k as u64 * 1_000_000;
        let header = mcap::records::MessageHeader {
            channel_id: channels[k % 2],
            sequence: k as u32,
            log_time: t_ns,
            publish_time: t_ns,
        };
        w.write_to_known_channel(&header, &data).unwrap();
    }
    w.finish().unwrap();
    std::fs::metadata(path).unwrap().len()
}

/// imu-rec's reader: messages and a checksum of their sequence numbers.
fn read_ours(path: &Path) -> (u64, u64) {
    let mut sum = 0u64;
    let report = imu_rec::mcap_read::for_each_message(path, |_, header, data| {
        sum = sum.wrapping_add(u64::from(header.sequence) ^ u64::from(data[0]));
        Ok(())
    })
    .unwrap();
    assert!(report.stopped_early.is_none());
    (report.n_messages, sum)
}

/// The crate's `LinearReader`, fed from the file, every record parsed.
fn read_crate(path: &Path) -> (u64, u64) {
    let mut file = File::open(path).unwrap();
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(1 << 30),
    );
    let (mut n, mut sum) = (0u64, 0u64);
    while let Some(event) = reader.next_event() {
        match event.unwrap() {
            LinearReadEvent::ReadRequest(need) => {
                let got = file.read(reader.insert(need)).unwrap();
                reader.notify_read(got);
            }
            LinearReadEvent::Record { opcode, data } => {
                if let mcap::records::Record::Message { header, data } =
                    mcap::parse_record(opcode, data).unwrap()
                {
                    n += 1;
                    sum = sum.wrapping_add(u64::from(header.sequence) ^ u64::from(data[0]));
                }
            }
        }
    }
    (n, sum)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let n = env_usize("IMUD_BENCH_MCAP_MESSAGES", 2_000_000);
    let runs = env_usize("IMUD_BENCH_RUNS", 5);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bench.mcap");
    let bytes = write(&path, n);
    let mib = bytes as f64 / f64::from(1 << 20);
    println!("file: {n} messages, {mib:.1} MiB (zstd chunks of 1 MiB)");
    let expect = read_crate(&path);
    assert_eq!(expect.0, n as u64);
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    // Alternated, so load changes hit both alike.
    for _ in 0..runs {
        let t = Instant::now();
        assert_eq!(read_ours(&path), expect);
        ours.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        assert_eq!(read_crate(&path), expect);
        theirs.push(t.elapsed().as_secs_f64());
    }
    let (o, c) = (median(ours), median(theirs));
    println!("reader                         median of {runs}   MiB/s   M messages/s");
    println!(
        "imu_rec::mcap_read             {o:8.3} s   {:7.0}   {:6.2}",
        mib / o,
        n as f64 / o / 1e6
    );
    println!(
        "mcap::LinearReader (crate)     {c:8.3} s   {:7.0}   {:6.2}",
        mib / c,
        n as f64 / c / 1e6
    );
    println!("ours / crate: {:.2}x the time", o / c);
}
