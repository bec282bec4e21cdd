//! The fuzz tier of CI: every committed corpus input and a fixed number of seeded mutations of
//! the corpus through each target's checks (byte accounting and events rebuilding the stream for
//! the decoders, re-encoding for the message decoders, cut files for the readers; no panic).
//! The count is fixed, not a time, so the tier is deterministic; the long runs and the
//! coverage-guided libFuzzer run are in BENCHMARKS.md.

use imu_fuzz::mutate::Mutator;
use imu_fuzz::{ALL, Target, corpus, run};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The failures of one target's tier, as text (empty when it passed).
fn fuzz_tier(target: &'static Target) -> Vec<String> {
    let dir = target.corpus_dir();
    let inputs = corpus::load(&dir).unwrap();
    assert!(
        inputs.len() >= 4,
        "{}: the committed corpus has only {} inputs",
        dir.display(),
        inputs.len()
    );
    let report = run(target, &inputs, target.ci_mutations, 0x1A2B);
    if report.failures.is_empty() {
        assert_eq!(report.inputs, inputs.len() as u64 + target.ci_mutations);
    }
    report
        .failures
        .iter()
        .map(|f| {
            format!(
                "{} input {} ({}): {}",
                target.name,
                f.index,
                hex(&f.input),
                f.message
            )
        })
        .collect()
}

#[test]
fn every_target_survives_its_corpus_and_mutations() {
    let failures: Vec<String> = ALL.iter().flat_map(|t| fuzz_tier(t)).collect();
    assert!(failures.is_empty(), "failed on:\n{}", failures.join("\n"));
}

#[test]
fn every_target_has_a_committed_corpus_and_a_unique_name() {
    let mut names: Vec<&str> = ALL.iter().map(|t| t.name).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), ALL.len(), "target names are unique");
    for t in ALL {
        assert!(t.corpus_dir().is_dir(), "{}: no corpus", t.name);
        assert_eq!(Target::from_name(t.name).map(|f| f.name), Some(t.name));
    }
}

#[test]
fn a_seed_reproduces_its_inputs_and_another_seed_does_not() {
    let mip = Target::from_name("mip_decoder").unwrap();
    let corpus = corpus::load(&mip.corpus_dir()).unwrap();
    let draw = |seed| {
        let mut m = Mutator::new(mip, seed);
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
