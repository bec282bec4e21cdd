//! `imu-fuzz`: the stable-Rust fuzz harness's command line. `imu-fuzz run` replays each target's
//! committed corpus and then N seeded mutations of it (the long runs of BENCHMARKS.md);
//! `imu-fuzz seed` writes the seed inputs a corpus starts from.

use std::fs;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use imu_fuzz::{Target, corpus, run, seeds};

#[derive(Parser)]
#[command(about = "Stable-Rust fuzz harness for the imu-proto decoders")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Check every corpus input, then N mutations of the corpus, for each target named (all by
    /// default); failing inputs are written to --artifacts and the exit code is 1.
    Run {
        /// Targets: reply_decoder, command_decoder, mip_decoder, vectornav_decoder.
        targets: Vec<String>,
        /// Mutated inputs per target (after the corpus).
        #[arg(long, default_value_t = 1_000_000)]
        inputs: u64,
        /// Seed of the mutator.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Corpus root holding one directory per target (default: the committed fuzz/corpus).
        #[arg(long)]
        corpus: Option<PathBuf>,
        /// Where failing inputs are written.
        #[arg(long, default_value = "target/fuzz-artifacts")]
        artifacts: PathBuf,
    },
    /// Write the seed inputs of each target named (all by default) into DIR/<target>/.
    Seed {
        /// Targets: reply_decoder, command_decoder, mip_decoder, vectornav_decoder.
        targets: Vec<String>,
        /// Corpus root.
        #[arg(long)]
        out: PathBuf,
    },
}

fn targets(names: &[String]) -> Result<Vec<Target>> {
    if names.is_empty() {
        return Ok(Target::ALL.to_vec());
    }
    names
        .iter()
        .map(|n| {
            Target::from_name(n).with_context(|| {
                let known: Vec<_> = Target::ALL.iter().map(|t| t.name()).collect();
                format!("unknown target `{n}` (targets: {})", known.join(", "))
            })
        })
        .collect()
}

fn main() -> ExitCode {
    match real_main() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("imu-fuzz: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn real_main() -> Result<ExitCode> {
    match Cli::parse().command {
        Cmd::Run {
            targets: names,
            inputs,
            seed,
            corpus: root,
            artifacts,
        } => {
            let mut failed = false;
            for target in targets(&names)? {
                let dir = root
                    .as_ref()
                    .map_or_else(|| target.corpus_dir(), |r| r.join(target.name()));
                let inputs_corpus = corpus::load(&dir)?;
                if inputs_corpus.is_empty() {
                    bail!("the corpus {} is empty", dir.display());
                }
                let report = run(target, &inputs_corpus, inputs, seed);
                let secs = report.elapsed.as_secs_f64();
                println!(
                    "{}: {} inputs ({} corpus), {} bytes, {} failures, {:.1} s, {:.0} inputs/s",
                    target.name(),
                    report.inputs,
                    report.corpus_inputs,
                    report.bytes,
                    report.failures.len(),
                    secs,
                    report.inputs as f64 / secs.max(1e-9)
                );
                for f in &report.failures {
                    fs::create_dir_all(&artifacts)
                        .with_context(|| format!("creating {}", artifacts.display()))?;
                    let path = artifacts.join(format!("{}-crash-{}", target.name(), f.index));
                    fs::write(&path, &f.input)
                        .with_context(|| format!("writing {}", path.display()))?;
                    println!("  input {} -> {}: {}", f.index, path.display(), f.message);
                    failed = true;
                }
            }
            Ok(if failed {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            })
        }
        Cmd::Seed {
            targets: names,
            out,
        } => {
            for target in targets(&names)? {
                let s = seeds::seeds(target);
                corpus::store(&out.join(target.name()), "seed", &s)?;
                println!("{}: {} seeds", target.name(), s.len());
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}
