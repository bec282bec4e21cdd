//! The VectorNav decoder alone, without the daemon around it: ns per binary message framed,
//! checked and decoded by `VnDecoder` (the message imud configures, 92 bytes), pushed one
//! message at a time as the daemon's reads hand them over. Prints the median and tail over
//! batches. Run: `cargo bench -p imu-proto --bench vectornav_decode`.

use std::time::Instant;

use imu_proto::vectornav::{BinaryData, BinaryMessage, VnDecoder, VnEvent, calibration_fields};

// Short batches (about 50 us): on a loaded machine most are not preempted, so the median is
// the decoder's cost rather than the scheduler's.
const BATCH: usize = 100;
const BATCHES: usize = 20_000;

fn main() {
    let messages: Vec<Vec<u8>> = (0..BATCH as u64)
        .map(|k| {
            let x = k as f32 * 1e-4;
            let data = BinaryData {
                startup_ns: Some(1_250_000 * k),
                uncomp_mag_gauss: Some([0.2, -0.1 + x, 0.45]),
                uncomp_accel_m_s2: Some([0.01 + x, -0.02, -9.81]),
                uncomp_gyro_rad_s: Some([1e-3, -2e-3, 3e-3 + x]),
                temp_c: Some(25.5),
                mag_gauss: Some([0.21, -0.11, 0.44]),
                accel_m_s2: Some([x, 0.0, -9.81]),
                angular_rate_rad_s: Some([0.0, x, 1e-3]),
                ..BinaryData::default()
            };
            BinaryMessage::encode(calibration_fields(false), &data)
                .expect("encodable")
                .as_bytes()
                .to_vec()
        })
        .collect();
    let mut d = VnDecoder::new();
    let mut per_message_ns = Vec::with_capacity(BATCHES);
    let mut sum = 0.0f64;
    for _ in 0..BATCHES {
        let t = Instant::now();
        for m in &messages {
            d.push(m);
            while let Some(ev) = d.next_event() {
                if let VnEvent::Binary { message, .. } = ev {
                    sum += f64::from(message.data().uncomp_accel_m_s2.map_or(0.0, |a| a[0]));
                }
            }
        }
        per_message_ns.push(t.elapsed().as_nanos() as f64 / BATCH as f64);
    }
    per_message_ns.sort_by(f64::total_cmp);
    let q = |p: f64| per_message_ns[((per_message_ns.len() - 1) as f64 * p) as usize];
    println!(
        "VnDecoder, {} bytes a message: min {:.0} median {:.0} ns/message, p90 {:.0}, p99 {:.0} \
         ({} messages, checksum {sum:.3})",
        messages[0].len(),
        q(0.0),
        q(0.5),
        q(0.9),
        q(0.99),
        BATCH * BATCHES
    );
}
