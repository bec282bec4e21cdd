//! Link dropouts: windows of scenario time in which the device's data replies never reach the
//! host (a loose connector, a USB hub resetting, a radio link fading), as real fleets' data
//! has them. Written ones (`[[dropout]]`, `at-s`, `duration-s`) and random ones
//! (`[random-dropouts]`, `per-hour`, `mean-duration-s`: a Poisson process of starts with
//! exponential durations, drawn from the scenario's seed in [`Scenario::compile`]). The truth
//! keeps every sample; what is lost is what the host sees.

use super::*;

/// A `[[dropout]]`: the link loses the device's data replies from `at-s` for `duration-s`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct DropoutSpec {
    /// Start, s of scenario time.
    pub at_s: f64,
    /// Length, s.
    pub duration_s: f64,
}

/// `[random-dropouts]`: dropouts at random times (a Poisson process of `per-hour` starts an
/// hour of scenario time) with exponentially distributed lengths of mean `mean-duration-s`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct RandomDropouts {
    /// Mean number of dropouts starting in an hour of scenario time.
    pub per_hour: f64,
    /// Mean length of a dropout, s.
    pub mean_duration_s: f64,
}

/// A window of scenario time `[start_s, end_s)` whose data replies are lost on the link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkDropout {
    /// Start, s of scenario time.
    pub start_s: f64,
    /// End, s (replies from here on arrive again).
    pub end_s: f64,
}

impl LinkDropout {
    /// True if a reply at scenario time `t_s` is lost.
    pub fn contains(&self, t_s: f64) -> bool {
        (self.start_s..self.end_s).contains(&t_s)
    }
}

/// Seed offset of the random dropouts' own stream (the other draws of a scenario are unchanged
/// by adding them).
const DROPOUT_SEED: u64 = 0xd209_0075_11a5;

impl Scenario {
    /// The dropout windows of a run with `seed` over a timeline of `duration_s`: the written
    /// ones and the random ones, in time order, overlapping random ones merged.
    pub(super) fn dropouts(&self, seed: u64, duration_s: f64) -> Vec<LinkDropout> {
        let mut out: Vec<LinkDropout> = self
            .dropouts
            .iter()
            .map(|d| LinkDropout {
                start_s: d.at_s,
                end_s: d.at_s + d.duration_s,
            })
            .collect();
        // (A scenario without an end has none: validation refuses them there.)
        let random = self.random_dropouts.filter(|r| r.per_hour > 0.0);
        if let Some(r) = random.filter(|_| duration_s.is_finite()) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ DROPOUT_SEED);
            // Exponential draws by inversion: -ln(1 - u) for u uniform in [0, 1).
            let mut exp = |mean: f64| -mean * (1.0 - rng.random::<f64>()).ln();
            let mean_gap_s = 3600.0 / r.per_hour;
            let mut t = exp(mean_gap_s);
            while t < duration_s {
                let end = (t + exp(r.mean_duration_s)).min(duration_s);
                out.push(LinkDropout {
                    start_s: t,
                    end_s: end,
                });
                t += exp(mean_gap_s);
            }
        }
        out.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        let mut merged: Vec<LinkDropout> = Vec::with_capacity(out.len());
        for d in out {
            match merged.last_mut() {
                Some(last) if d.start_s <= last.end_s => last.end_s = last.end_s.max(d.end_s),
                _ => merged.push(d),
            }
        }
        merged
    }

    /// Dropouts inside the scenario, of positive length, not overlapping; random dropouts at a
    /// rate >= 0 with a positive mean length, in a scenario that ends. Errors name the file and
    /// the line of the table (`text` is the file's text).
    pub(super) fn validate_dropouts(&self, file: &str, text: &str) -> Result<(), ScenarioError> {
        let at =
            |context: String, header: &str, nth: usize, message: String| ScenarioError::InvalidAt {
                file: file.to_string(),
                line: header_line(text, header, nth),
                context,
                message,
            };
        if self.dropouts.is_empty() && self.random_dropouts.is_none() {
            return Ok(());
        }
        let duration_s = self.compile(self.seed).duration_s();
        for (i, d) in self.dropouts.iter().enumerate() {
            let context = format!("dropout {}", i + 1);
            if !(d.at_s.is_finite() && d.at_s >= 0.0) {
                return Err(at(
                    context,
                    "[[dropout]]",
                    i,
                    format!("at-s = {} must be a scenario time >= 0", d.at_s),
                ));
            }
            if !(d.duration_s.is_finite() && d.duration_s > 0.0) {
                return Err(at(
                    context,
                    "[[dropout]]",
                    i,
                    format!("duration-s = {} must be positive", d.duration_s),
                ));
            }
            if d.at_s + d.duration_s > duration_s {
                return Err(at(
                    context,
                    "[[dropout]]",
                    i,
                    format!(
                        "{} s to {} s is not inside the scenario (0 to {duration_s} s)",
                        d.at_s,
                        d.at_s + d.duration_s
                    ),
                ));
            }
            if let Some((j, o)) = self
                .dropouts
                .iter()
                .enumerate()
                .take(i)
                .find(|(_, o)| d.at_s < o.at_s + o.duration_s && o.at_s < d.at_s + d.duration_s)
            {
                return Err(at(
                    context,
                    "[[dropout]]",
                    i,
                    format!(
                        "{} s to {} s overlaps dropout {} ({} s to {} s): make them one",
                        d.at_s,
                        d.at_s + d.duration_s,
                        j + 1,
                        o.at_s,
                        o.at_s + o.duration_s
                    ),
                ));
            }
        }
        if let Some(r) = self.random_dropouts {
            let bad =
                |message: String| at("random-dropouts".into(), "[random-dropouts]", 0, message);
            if !(r.per_hour.is_finite() && r.per_hour >= 0.0) {
                return Err(bad(format!("per-hour = {} must be >= 0", r.per_hour)));
            }
            if !(r.mean_duration_s.is_finite() && r.mean_duration_s > 0.0) {
                return Err(bad(format!(
                    "mean-duration-s = {} must be positive",
                    r.mean_duration_s
                )));
            }
            if !duration_s.is_finite() {
                return Err(bad(
                    "random dropouts need a scenario that ends (give the last segment a \
                     duration-s)"
                        .into(),
                ));
            }
        }
        Ok(())
    }
}

/// The 1-based line of the `nth` (0-based) table header `header` in `text` (line 1 if the
/// table is written inline).
fn header_line(text: &str, header: &str, nth: usize) -> usize {
    text.lines()
        .enumerate()
        .filter(|(_, l)| l.trim_start().starts_with(header))
        .nth(nth)
        .map_or(1, |(i, _)| i + 1)
}
