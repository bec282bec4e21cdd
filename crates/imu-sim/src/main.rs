//! `imu-sim`: run a virtual MicroStrain 3DM-GX1 (or a MIP unit) on a pseudo-terminal.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use imu_proto::DeviceProtocol;
use imu_sim::export::ExportUnits;
use imu_sim::{Pacing, SimOptions};

/// A virtual MicroStrain 3DM-GX1 IMU (or, with --protocol mip, a MIP unit like a 3DM-GX5) on a
/// pseudo-terminal, driven by known physics and a known error model.
///
/// The first line on stdout is the device path (e.g. /dev/pts/7); open it with imud, a serial
/// terminal or any 3DM-GX1 driver and speak the documented protocol. The device starts idle, like
/// a real one after power-on: the scenario clock starts at the first data request (a poll such as
/// 0x01 or 0x07, or continuous mode 10 00 <cmd>); with --power-up-streaming it streams from
/// power-up instead. The program exits 0 when the scenario ends.
///
/// The scenario (TOML, see config/scenarios/) says how the sensor moves: static positions,
/// index-table steps, rate-table plateaus, rotations, impacts, random poses; the latitude (Earth
/// rate), gravity, magnetic field, temperature profile, and the device's identity, GainScales,
/// tick period and clock drift. The truth model (an imu-model calibration file, see
/// config/models/) says which errors the sensor has: any effect of the library can be hidden in
/// the data. The truth file (--truth-out, MCAP) records for every data reply the true specific
/// force, angular rate, temperature, orientation, table angle, segment and the pre-quantization
/// measurement, keyed by the reply's timer ticks, plus the scenario, seed and truth model.
///
/// Signals: SIGTERM/SIGINT stop and finish the truth file; SIGUSR1 simulates unplugging the
/// device for 2 s (the pty closes, a new one appears at the same --link path).
#[derive(Debug, Parser)]
#[command(name = "imu-sim", version)]
struct Args {
    /// Scenario file (TOML).
    #[arg(long, value_name = "FILE")]
    scenario: PathBuf,
    /// Truth error model (imu-model calibration TOML); overrides the scenario's `truth` key.
    /// Without either the sensor is perfect apart from 16-bit quantization.
    #[arg(long, value_name = "MODEL.toml")]
    truth: Option<PathBuf>,
    /// Random seed for noise and random poses (default: the scenario's `seed`).
    #[arg(long, value_name = "N")]
    seed: Option<u64>,
    /// Write the ground truth of every data reply to this MCAP file.
    #[arg(long, value_name = "FILE")]
    truth_out: Option<PathBuf>,
    /// Also expose the device at this stable path (a symlink to the pty, replaced if it exists).
    #[arg(long, value_name = "PATH")]
    link: Option<PathBuf>,
    /// Run on a virtual clock as fast as the host reads (tests), instead of in real time at the
    /// scenario rate and baud rate.
    #[arg(long)]
    fast: bool,
    /// Seconds to wait at the end of the scenario for the host to read the last bytes.
    #[arg(long, value_name = "S", default_value_t = 5.0, value_parser = imu_cli::finite_f64)]
    linger_s: f64,
    /// The protocol the device speaks: 3dm-gx1, mip, xsens or vectornav (default: the
    /// scenario's `device.protocol`, else 3dm-gx1). A MIP device powers up idle with streaming
    /// enabled; `resume` (base command 0x06) starts the stream, see imu_sim::mip_device. An Xsens
    /// MTi powers up streaming its default outputs, see imu_sim::xsens_device; a VectorNav unit
    /// streaming `$VNYPR` at 40 Hz, see imu_sim::vectornav_device.
    #[arg(long, value_name = "PROTOCOL")]
    protocol: Option<DeviceProtocol>,
    /// The device powers up streaming, without any command, as a unit set up and saved with the
    /// vendor's tool: a 3DM-GX1 in continuous mode (raw sensor bits, 0x01), a MIP unit with its
    /// IMU stream resumed, a VectorNav unit with binary output 1 on; the scenario clock starts at once (scenario key
    /// `device.power-up-streaming`).
    #[arg(long)]
    power_up_streaming: bool,
    /// Print the scenario's segments and duration and exit without opening a device.
    #[arg(long)]
    describe: bool,
    /// Instead of opening a device, run the scenario at CPU speed and write it to DIR as two
    /// whitespace-separated text files without a header, `acc.txt` and `gyro.txt`, one
    /// `t x y z` line per sample at the scenario rate (t in s from the start): the device's
    /// replies to raw-sensor-bits polls, with --truth-out their truth. Prints the files and the
    /// `counts:SCALE@32768` unit that reads them.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["link", "fast", "describe"])]
    export_text: Option<PathBuf>,
    /// Units of --export-text: raw-counts (the device's unsigned 16-bit counts, zero at
    /// 32768, one count GainScale / 32 768 000 g or rad/s) or si (m/s^2 and rad/s).
    #[arg(
        long,
        value_name = "UNITS",
        default_value = "raw-counts",
        requires = "export_text"
    )]
    export_units: ExportUnits,
    /// Instead of opening a device, run the scenario at CPU speed and write the samples of its
    /// parts (segments with a `part`) to FILE as a labelled session without time, as labs
    /// export one for the Python package imucal: `part,samples,acc_x,...,gyr_z`, `samples` the
    /// index within the part, signed counts, the moves between parts cut out. Prints the parts
    /// and the flags that read it.
    #[arg(long, value_name = "FILE.csv", conflicts_with_all = ["link", "fast", "describe", "export_text"])]
    export_parts: Option<PathBuf>,
    /// With --export-parts: negate the gyro's counts (a unit whose gyro reports rotation the
    /// other way).
    #[arg(long, requires = "export_parts")]
    export_flip_gyro: bool,
}

fn main() -> std::process::ExitCode {
    imu_cli::main("imu-sim", run)
}

fn run(args: Args) -> anyhow::Result<()> {
    let mut opts = SimOptions::from_files(&args.scenario, args.truth.as_deref())?;
    if let Some(seed) = args.seed {
        opts.seed = seed;
    }
    if let Some(protocol) = args.protocol {
        opts.scenario
            .set_protocol(protocol, &args.scenario.display().to_string())?;
    }
    opts.scenario.device.power_up_streaming |= args.power_up_streaming;
    if args.describe {
        return describe(&opts);
    }
    opts.truth_out = args.truth_out;
    if let Some(dir) = &args.export_text {
        return export(&opts, dir, args.export_units);
    }
    if let Some(path) = &args.export_parts {
        return export_parts(&opts, path, args.export_flip_gyro);
    }
    opts.link = args.link;
    opts.pacing = if args.fast {
        Pacing::Fast
    } else {
        Pacing::RealTime
    };
    opts.linger = Duration::try_from_secs_f64(args.linger_s)
        .context("--linger-s must be a non-negative number of seconds")?;
    let s = &opts.scenario;
    let frame_bytes_per_s = s.rate_hz * 23.0 * 10.0;
    if !args.fast
        && s.device.protocol == DeviceProtocol::Gx1
        && frame_bytes_per_s > s.device.baud as f64
    {
        eprintln!(
            "imu-sim: warning: {} Hz of 23-byte frames needs {:.0} baud but the device is set to {}; \
             samples the link cannot carry are skipped",
            s.rate_hz, frame_bytes_per_s, s.device.baud
        );
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        signal_hook::flag::register(sig, stop.clone()).context("installing signal handlers")?;
    }
    // SIGUSR1 simulates pulling the cable for two seconds (reconnect testing by hand).
    let unplug = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, unplug.clone())
        .context("installing signal handlers")?;
    let handle = imu_sim::spawn(opts)?;
    {
        let mut out = std::io::stdout().lock();
        // A closed stdout must not stop the device: scripts often read only this first line.
        let _ = writeln!(out, "{}", handle.device_path().display());
        let _ = out.flush();
    }
    while !handle.is_finished() {
        if stop.load(Ordering::Relaxed) {
            handle.stop();
        }
        if unplug.swap(false, Ordering::Relaxed) {
            eprintln!("imu-sim: SIGUSR1: unplugging the device for 2 s");
            handle.unplug(Duration::from_secs(2));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let report = handle.join()?;
    eprintln!(
        "imu-sim: {} data replies, {} bytes out, {} bytes in ({} rejected), scenario time {:.3} s{}",
        report.data_replies,
        report.bytes_out,
        report.bytes_in,
        report.rejected_command_bytes,
        report.scenario_time_s,
        if report.samples_skipped_link_busy > 0 {
            format!(
                ", {} samples skipped (link busy)",
                report.samples_skipped_link_busy
            )
        } else {
            String::new()
        }
    );
    Ok(())
}

fn export(opts: &SimOptions, dir: &std::path::Path, units: ExportUnits) -> anyhow::Result<()> {
    let out = imu_sim::export::export_text(opts, dir, units)?;
    let mut stdout = std::io::stdout().lock();
    let _ = writeln!(
        stdout,
        "{} samples: {} {}",
        out.samples,
        out.accel.display(),
        out.gyro.display()
    );
    if units == ExportUnits::RawCounts {
        let _ = writeln!(
            stdout,
            "read with: --csv-accel counts:{}@32768 --csv-gyro counts:{}@32768",
            out.accel_count_m_s2, out.gyro_count_rad_s
        );
    }
    Ok(())
}

fn export_parts(opts: &SimOptions, path: &std::path::Path, flip_gyro: bool) -> anyhow::Result<()> {
    let sign = if flip_gyro { -1 } else { 1 };
    let out = imu_sim::export::export_parts(opts, path, sign)?;
    let mut stdout = std::io::stdout().lock();
    let parts: Vec<String> = out
        .parts
        .iter()
        .map(|(name, _, n)| format!("{name} ({n})"))
        .collect();
    let _ = writeln!(
        stdout,
        "{} samples in {} parts: {}\n{}",
        out.samples,
        out.parts.len(),
        parts.join(", "),
        out.path.display()
    );
    let _ = writeln!(
        stdout,
        "read with: --rate-hz {} --columns acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z --csv-accel \
         counts:{} --csv-gyro counts:{}",
        out.rate_hz,
        out.accel_count_m_s2,
        f64::from(sign) * out.gyro_count_rad_s
    );
    Ok(())
}

fn describe(opts: &SimOptions) -> anyhow::Result<()> {
    let timeline = opts.scenario.compile(opts.seed);
    let mut out = std::io::stdout().lock();
    let s = &opts.scenario;
    let _ = writeln!(out, "scenario {}: {}", s.name, s.description.trim());
    let _ = writeln!(
        out,
        "rate {} Hz, latitude {} deg, seed {}, duration {:.3} s",
        s.rate_hz,
        s.latitude_deg,
        opts.seed,
        timeline.duration_s()
    );
    for seg in timeline.segments() {
        let g = seg.gravity_dir_sensor;
        let _ = writeln!(
            out,
            "{:>5} {:>9.3} s .. {:>9} {:<8} gravity [{:+.3} {:+.3} {:+.3}]  {}",
            seg.index,
            seg.start_s,
            seg.end_s.map_or("end".into(), |e| format!("{e:.3} s")),
            seg.kind,
            g.x,
            g.y,
            g.z,
            seg.label
        );
    }
    Ok(())
}
