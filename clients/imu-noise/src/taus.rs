//! The `--taus` argument: a named tau set of the library, or an explicit list of taus in
//! seconds, turned into averaging factors once the sample rate is known.

use anyhow::Result;
use imu_stats::allan::TauSet;

/// What `--taus` asked for.
#[derive(Debug, Clone, PartialEq)]
pub enum TauArg {
    /// A named set (`octave`, `decade`, `all`, `N-per-decade`).
    Set(TauSet),
    /// These taus, seconds (`1,2,4,10`).
    Seconds(Vec<f64>),
}

impl std::str::FromStr for TauArg {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if let Ok(set) = s.parse::<TauSet>() {
            return Ok(TauArg::Set(set));
        }
        if !s.starts_with(|c: char| c.is_ascii_digit() || c == '.') {
            return Err(format!(
                "bad tau set {s:?}: use octave, decade, all, N-per-decade or a list of taus in \
                 seconds such as 1,2,4,10"
            ));
        }
        let taus = s
            .split(',')
            .map(|t| match t.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
                _ => Err(format!(
                    "bad tau {t:?} in {s:?}: each tau is a positive number of seconds"
                )),
            })
            .collect::<Result<Vec<f64>, String>>()?;
        Ok(TauArg::Seconds(taus))
    }
}

impl TauArg {
    /// The library tau set at sample rate `rate_hz`: explicit taus become the nearest averaging
    /// factor (tau = m / rate); a tau shorter than half a sample period is an error.
    pub fn resolve(&self, rate_hz: f64) -> Result<TauSet> {
        match self {
            TauArg::Set(set) => Ok(set.clone()),
            TauArg::Seconds(taus) => {
                let ms = taus
                    .iter()
                    .map(|&tau_s| {
                        let m = (tau_s * rate_hz).round();
                        anyhow::ensure!(
                            m >= 1.0,
                            "tau {tau_s} s is shorter than the sample period {:.6} s",
                            1.0 / rate_hz
                        );
                        Ok(m as usize)
                    })
                    .collect::<Result<Vec<usize>>>()?;
                Ok(TauSet::Factors(ms))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sets_and_lists() {
        assert_eq!("decade".parse(), Ok(TauArg::Set(TauSet::Decade)));
        assert_eq!(
            "1,2,4,10".parse(),
            Ok(TauArg::Seconds(vec![1.0, 2.0, 4.0, 10.0]))
        );
        assert_eq!("0.5".parse(), Ok(TauArg::Seconds(vec![0.5])));
        assert!("1,x".parse::<TauArg>().is_err());
        assert!("1,-2".parse::<TauArg>().is_err());
        assert!("octav".parse::<TauArg>().is_err());
        let set = TauArg::Seconds(vec![1.0, 0.25]).resolve(100.0).unwrap();
        assert_eq!(set, TauSet::Factors(vec![100, 25]));
        assert!(TauArg::Seconds(vec![0.001]).resolve(100.0).is_err());
    }
}
