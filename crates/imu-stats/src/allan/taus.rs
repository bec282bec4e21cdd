//! Tau sets: which averaging factors m (tau = m tau0) a deviation curve is evaluated at.

use serde::Serialize;

/// Which averaging factors m (tau = m tau0) to evaluate.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub enum TauSet {
    /// m = 1, 2, 4, 8, ... up to the kind's limit.
    Octave,
    /// Stable32's decade set: m = 1, 2, 4 times 10^k (1, 2, 4, 10, 20, 40, 100, ...).
    Decade,
    /// `n` log-spaced m per decade (rounded, duplicates removed), starting at m = 1.
    PerDecade(u32),
    /// m = 1, 2, 3, ... every factor (slow for long series; for short ones and tests).
    All,
    /// These averaging factors (sorted and deduplicated; zero and those beyond the kind's limit
    /// are left out).
    Factors(Vec<usize>),
}

impl TauSet {
    /// The averaging factors up to the given maximum m, increasing.
    pub fn factors(&self, max_m: usize) -> Vec<usize> {
        let mut out = Vec::new();
        match self {
            TauSet::Octave => {
                let mut m = 1usize;
                while m <= max_m {
                    out.push(m);
                    m = m.saturating_mul(2);
                }
            }
            TauSet::Decade => {
                let mut decade = 1usize;
                'outer: loop {
                    for step in [1, 2, 4] {
                        let m = decade.saturating_mul(step);
                        if m > max_m {
                            break 'outer;
                        }
                        out.push(m);
                    }
                    decade = decade.saturating_mul(10);
                }
            }
            TauSet::PerDecade(n) => {
                let n = f64::from((*n).max(1));
                let mut k = 0u32;
                loop {
                    let m = 10f64.powf(f64::from(k) / n).round() as usize;
                    if m > max_m {
                        break;
                    }
                    if out.last() != Some(&m) {
                        out.push(m);
                    }
                    k += 1;
                }
            }
            TauSet::All => out.extend(1..=max_m),
            TauSet::Factors(ms) => {
                out.extend(ms.iter().copied().filter(|&m| m >= 1 && m <= max_m));
                out.sort_unstable();
                out.dedup();
            }
        }
        out
    }
}

impl std::str::FromStr for TauSet {
    type Err = String;

    /// Parses `octave`, `decade`, `all` or `N-per-decade` (e.g. `10-per-decade`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "octave" => Ok(TauSet::Octave),
            "decade" => Ok(TauSet::Decade),
            "all" => Ok(TauSet::All),
            _ => s
                .strip_suffix("-per-decade")
                .and_then(|n| n.parse::<u32>().ok())
                .filter(|&n| n > 0)
                .map(TauSet::PerDecade)
                .ok_or_else(|| {
                    format!("bad tau set {s:?}: use octave, decade, all or N-per-decade")
                }),
        }
    }
}
