//! The fuzz tier of CI: every committed corpus input and a fixed number of seeded mutations of
//! the corpus through each decoder's checks (byte accounting, events rebuilding the stream, no
//! panic). The count is fixed, not a time, so the tier is deterministic; the long runs and the
//! coverage-guided cargo-fuzz targets are in BENCHMARKS.md.

use imu_fuzz::mutate::Mutator;
use imu_fuzz::{Target, corpus, run};

/// Mutated inputs per target in CI (a few seconds each in the test profile).
const CI_MUTATIONS: u64 = 1_000_000;

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn fuzz_tier(target: Target) {
    let dir = target.corpus_dir();
    let inputs = corpus::load(&dir).unwrap();
    assert!(
        inputs.len() >= 20,
        "{}: the committed corpus has only {} inputs",
        dir.display(),
        inputs.len()
    );
    let report = run(target, &inputs, CI_MUTATIONS, 0x1A2B);
    assert_eq!(report.inputs, inputs.len() as u64 + CI_MUTATIONS);
    let failures: Vec<String> = report
        .failures
        .iter()
        .map(|f| format!("input {} ({}): {}", f.index, hex(&f.input), f.message))
        .collect();
    assert!(
        failures.is_empty(),
        "{} failed on:\n{}",
        target.name(),
        failures.join("\n")
    );
}

#[test]
fn reply_decoder_survives_its_corpus_and_mutations() {
    fuzz_tier(Target::ReplyDecoder);
}

#[test]
fn command_decoder_survives_its_corpus_and_mutations() {
    fuzz_tier(Target::CommandDecoder);
}

#[test]
fn mip_decoder_survives_its_corpus_and_mutations() {
    fuzz_tier(Target::MipDecoder);
}

#[test]
fn vectornav_decoder_survives_its_corpus_and_mutations() {
    fuzz_tier(Target::VectornavDecoder);
}

#[test]
fn a_seed_reproduces_its_inputs_and_another_seed_does_not() {
    let corpus = corpus::load(&Target::MipDecoder.corpus_dir()).unwrap();
    let draw = |seed| {
        let mut m = Mutator::new(Target::MipDecoder, seed);
        let mut out = Vec::new();
        (0..200)
            .map(|_| {
                m.next_input(&corpus, &mut out);
                out.clone()
            })
            .collect::<Vec<_>>()
    };
    let a = draw(7);
    assert_eq!(a, draw(7));
    assert_ne!(a, draw(8));
    // Mutations change the corpus inputs rather than copying them.
    assert!(a.iter().filter(|i| !corpus.contains(i)).count() > 190);
}
