//! The recording side of the scaled-time soak (`tests/soak_offline.rs`): runs a simulator
//! scenario through `imud::offline::record` (what `imud --sim SCENARIO --offline` runs, less
//! the truth file, which at a day of 1 kHz would not fit the disk) in a process of its own, so
//! the soak measures the recorder's resident memory alone while it reads back, checks and
//! deletes each rotated file as it is closed.
//!
//! Usage: `soak_offline_record SCENARIO.toml CONFIG.toml`; prints `samples N` when done.

use std::path::PathBuf;

use anyhow::Context;

fn main() -> anyhow::Result<()> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [scenario, config] = args.as_slice() else {
        anyhow::bail!("usage: soak_offline_record SCENARIO.toml CONFIG.toml");
    };
    let sim = imu_sim::SimOptions::from_files(scenario, None)?;
    let text =
        std::fs::read_to_string(config).with_context(|| format!("reading {}", config.display()))?;
    let config = imud::config::Config::from_toml_str(&text, &config.display().to_string())?;
    let report = imud::offline::record(sim, &config)?;
    println!("samples {}", report.samples);
    Ok(())
}
