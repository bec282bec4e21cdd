//! Unit tests of the workbench's private helpers.

use super::*;

#[test]
fn every_effect_has_physical_words_for_its_parameters() {
    for k in EffectKind::ALL {
        for t in [Triad::Accel, Triad::Gyro] {
            if !k.applies_to(t) {
                continue;
            }
            let mut m = TriadModel::default();
            m.add(k);
            for name in m.param_names(t) {
                let d = driver(k, &name, t);
                assert!(!d.contains('?') && d.contains(t.name()), "{name}: {d}");
            }
        }
    }
}
