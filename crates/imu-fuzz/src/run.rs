//! The stable harness's run: the corpus first, then seeded mutations of it; every input through
//! the target's checks with panics caught, so a failure is reported with the input that caused it.

use std::panic::{self, AssertUnwindSafe};
use std::time::{Duration, Instant};

use crate::Target;
use crate::mutate::Mutator;

/// A run stops after this many failing inputs (each is reported).
const MAX_FAILURES: usize = 8;

/// An input on which a check failed.
#[derive(Debug, Clone)]
pub struct Failure {
    /// The input, as the target takes it (chunk sizes and parameters first).
    pub input: Vec<u8>,
    /// The panic's message (the invariant that broke, or the decoder's own panic).
    pub message: String,
    /// 0-based index of the input in the run (corpus entries first).
    pub index: u64,
}

/// What a run did.
#[derive(Debug, Clone)]
pub struct RunReport {
    /// The target run.
    pub target: &'static Target,
    /// Inputs checked: corpus entries plus mutations (fewer if it stopped on failures).
    pub inputs: u64,
    /// Of those, the corpus entries.
    pub corpus_inputs: u64,
    /// Bytes of input checked in total.
    pub bytes: u64,
    /// Failing inputs (at most 8; the run stops there).
    pub failures: Vec<Failure>,
    /// Wall-clock time of the run (for the benchmark record, never asserted).
    pub elapsed: Duration,
    /// The longest any one input took, and its index (the work per input is bounded when a
    /// long run's slowest input stays short; recorded, never asserted).
    pub slowest: (Duration, u64),
    /// That input (to look at what made it slow).
    pub slowest_input: Vec<u8>,
}

/// Checks every corpus input, then `n_mutations` inputs mutated from the corpus with `seed`.
///
/// The default panic hook prints each caught panic to stderr as well; the report holds them.
pub fn run(target: &'static Target, corpus: &[Vec<u8>], n_mutations: u64, seed: u64) -> RunReport {
    let start = Instant::now();
    let mut report = RunReport {
        target,
        inputs: 0,
        corpus_inputs: 0,
        bytes: 0,
        failures: Vec::new(),
        elapsed: Duration::ZERO,
        slowest: (Duration::ZERO, 0),
        slowest_input: Vec::new(),
    };
    let check = |input: &[u8], report: &mut RunReport| {
        let started = Instant::now();
        let outcome = panic::catch_unwind(AssertUnwindSafe(|| target.check(input)));
        let took = started.elapsed();
        if took > report.slowest.0 {
            report.slowest = (took, report.inputs);
            report.slowest_input = input.to_vec();
        }
        if let Err(payload) = outcome {
            let message = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                .unwrap_or_else(|| "a panic without a message".to_owned());
            report.failures.push(Failure {
                input: input.to_vec(),
                message,
                index: report.inputs,
            });
        }
        report.inputs += 1;
        report.bytes += input.len() as u64;
        report.failures.len() < MAX_FAILURES
    };
    let mut going = true;
    for input in corpus {
        going = check(input, &mut report);
        report.corpus_inputs += 1;
        if !going {
            break;
        }
    }
    let mut mutator = Mutator::new(target, seed);
    let mut input = Vec::with_capacity(crate::mutate::MAX_INPUT_LEN);
    let mut n = 0;
    while going && n < n_mutations {
        mutator.next_input(corpus, &mut input);
        going = check(&input, &mut report);
        n += 1;
    }
    report.elapsed = start.elapsed();
    report
}
