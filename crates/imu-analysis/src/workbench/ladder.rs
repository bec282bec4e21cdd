//! The ladder: add the best claimed effect until both triads are consistent, then the final,
//! loadable calibration.

use super::*;

impl<'a> Workbench<'a> {
    /// The ladder: from `base` (accel and gyro models), repeatedly add the best claimed effect
    /// of a triad that is not yet consistent with its noise floor, until both are consistent
    /// or nothing more is claimed.
    pub fn ladder(&self, base: &imu_model::Calibration) -> Result<Ladder, DiagnoseError> {
        let mut models = [base.accel.clone(), base.gyro.clone()];
        let triads = [Triad::Accel, Triad::Gyro];
        let mut steps = Vec::new();
        let mut added: Vec<(Triad, EffectKind)> = Vec::new();
        let mut held_out: Option<HeldOut> = None;
        let mut base_diagnoses = None;
        // The last step's diagnoses and which triad's model changed since: a diagnosis depends
        // on its own triad's model alone, so the other triad's is kept, not recomputed.
        let mut previous: Option<([TriadDiagnosis; 2], usize)> = None;
        loop {
            let diags = match previous.take() {
                Some(([accel, _], 1)) => [accel, self.diagnose(Triad::Gyro, &models[1])?],
                Some(([_, gyro], _)) => [self.diagnose(Triad::Accel, &models[0])?, gyro],
                None => [
                    self.diagnose(Triad::Accel, &models[0])?,
                    self.diagnose(Triad::Gyro, &models[1])?,
                ],
            };
            if base_diagnoses.is_none() {
                base_diagnoses = Some(diags.clone());
            }
            steps.push(LadderStep {
                added: added.last().copied(),
                held_out: held_out.take(),
                accel: StepSummary::of(&diags[0]),
                gyro: StepSummary::of(&diags[1]),
            });
            let pick = diags
                .iter()
                .enumerate()
                .filter_map(|(i, d)| d.candidates.iter().find(|c| c.claimed).map(|c| (i, c)))
                .max_by(|a, b| a.1.delta_aic.total_cmp(&b.1.delta_aic));
            let Some((i, c)) = pick else {
                let (calibration, notes) = self.final_calibration(base, &diags);
                return Ok(Ladder {
                    steps,
                    base_diagnoses: base_diagnoses.take().unwrap_or_else(|| diags.clone()),
                    final_diagnoses: diags,
                    calibration,
                    notes,
                });
            };
            if steps.len() > self.opts.max_steps {
                let (calibration, notes) = self.final_calibration(base, &diags);
                return Ok(Ladder {
                    steps,
                    base_diagnoses: base_diagnoses.take().unwrap_or_else(|| diags.clone()),
                    final_diagnoses: diags,
                    calibration,
                    notes,
                });
            }
            added.push((triads[i], c.effect));
            held_out = c.held_out.clone();
            models[i] = c
                .model
                .clone()
                .expect("claimed candidates carry their refitted model");
            previous = Some((diags, i));
        }
    }

    pub(super) fn final_calibration(
        &self,
        base: &imu_model::Calibration,
        diags: &[TriadDiagnosis; 2],
    ) -> (imu_model::Calibration, crate::note::Notes) {
        use crate::note::Note;
        let mut notes = self.notes.clone();
        let mut cal = base.clone();
        cal.accel = diags[0].fit.model.clone();
        cal.gyro = diags[1].fit.model.clone();
        if self.reference_free_magnitude().is_none() {
            // A model imud would reject (e.g. a cubic term extrapolated over the full range) is
            // refitted with the offending parameter held, as imu-calibrate does.
            for (d, t) in diags.iter().zip([Triad::Accel, Triad::Gyro]) {
                if d.fit.model.validate(t).is_ok() {
                    continue;
                }
                let (points, _, _) = self.points(t);
                let one = crate::calibrate::Sessions::default();
                match crate::calibrate::fit_loadable(
                    &d.fit.model,
                    t,
                    points,
                    &one,
                    &self.fit_opts(t),
                ) {
                    Ok(r) => {
                        notes.extend(r.unobservable.iter().map(|u| Note::RefitHeld {
                            triad: t,
                            unobservable: u.clone(),
                        }));
                        *cal.triad_mut(t) = r.model;
                    }
                    Err(e) => notes.push(Note::RefitFailed {
                        triad: t,
                        error: e.to_string(),
                    }),
                }
            }
        }
        if let Some(mag) = self.reference_free_magnitude() {
            // Reference-free: the gyro gains come from the moves; the final model (the
            // ladder's accel and gyro offsets, the base's gyro gains) is calibrated as
            // imu-calibrate --reference-free does.
            let o = crate::calibrate::reference_free::ReferenceFreeOptions {
                accel: diags[0].fit.model.clone(),
                gyro: diags[1].fit.model.clone(),
                gravity_m_s2: mag.gravity_m_s2,
                latitude_deg: mag.latitude_deg,
                segment: self.opts.segment.clone(),
                ..Default::default()
            };
            match crate::calibrate::reference_free::calibrate_reference_free(self.series, &o) {
                Ok(f) => {
                    cal.accel = f.calibration.accel;
                    cal.gyro = f.calibration.gyro;
                    for n in f.notes {
                        if !notes.contains(&n) {
                            notes.push(n);
                        }
                    }
                }
                Err(e) => notes.push(Note::FinalCalibrationFailed {
                    error: e.to_string(),
                }),
            }
        }
        (cal, notes)
    }
}
