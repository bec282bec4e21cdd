//! Whole-triad operations over the registered effects: forward/inverse chains and the flat
//! parameter vector used by fitting tools.

use crate::effect::{InvalidParam, check_finite};
use crate::{Conditions, EffectKind, Triad, TriadModel, Vec3};

impl TriadModel {
    /// Truth -> measurement (no noise): apply the present effects in canonical order.
    pub fn forward(&self, true_input: Vec3, c: &Conditions) -> Vec3 {
        self.effect_slots()
            .into_iter()
            .flatten()
            .fold(true_input, |v, e| e.forward(v, c))
    }

    /// Measurement -> truth: undo the present effects in reverse canonical order.
    pub fn inverse(&self, measured: Vec3, c: &Conditions) -> Vec3 {
        self.effect_slots()
            .into_iter()
            .rev()
            .flatten()
            .fold(measured, |v, e| e.inverse(v, c))
    }

    /// [`TriadModel::inverse`] of every value of `measured` in place, all at the same
    /// conditions `c` (the samples of one move, say): bit-for-bit the same values, with each
    /// effect's per-call preparation (the misalignment's factorisation) made once per batch.
    pub fn inverse_batch(&self, measured: &mut [Vec3], c: &Conditions) {
        for e in self.effect_slots().into_iter().rev().flatten() {
            e.inverse_batch(measured, c);
        }
    }

    /// The paper's base model (Eq. 1-2): bias, scale and misalignment, all zero.
    pub const PAPER_BASE: [EffectKind; 3] = [
        EffectKind::Bias,
        EffectKind::Scale,
        EffectKind::Misalignment,
    ];

    /// A model with the effects `kinds` at their neutral values.
    pub fn with_effects(kinds: &[EffectKind]) -> TriadModel {
        let mut m = TriadModel::default();
        for k in kinds {
            m.add(*k);
        }
        m
    }

    /// The effects and their values only: without noise characterisation, residual
    /// statistics and standard errors (a model to fit, from a calibration file).
    pub fn effects_only(&self) -> TriadModel {
        let mut out = self.clone();
        out.noise = None;
        out.residual_rms = None;
        out.set_std_errors(None);
        out
    }

    /// Kinds of the present effects, in canonical order.
    pub fn kinds(&self) -> Vec<EffectKind> {
        self.effects().iter().map(|e| e.kind()).collect()
    }

    /// True if there are no effects, no noise and no residual statistics.
    pub fn is_empty(&self) -> bool {
        self.effects().is_empty() && self.noise.is_none() && self.residual_rms.is_none()
    }

    /// All parameters of the present effects, concatenated in canonical order.
    pub fn params(&self) -> Vec<f64> {
        self.effects().iter().flat_map(|e| e.params()).collect()
    }

    /// Total number of parameters.
    pub fn n_params(&self) -> usize {
        self.effects().iter().map(|e| e.n_params()).sum()
    }

    /// Replace all parameters (the layout of [`TriadModel::params`]). The length must equal
    /// [`TriadModel::n_params`] (debug-asserted; in release a short vector leaves the remaining
    /// parameters unchanged).
    pub fn set_params(&mut self, p: &[f64]) {
        debug_assert_eq!(p.len(), self.n_params(), "parameter vector length mismatch");
        let mut rest = p;
        for e in self.effects_mut() {
            let n = e.n_params().min(rest.len());
            e.set_params(&rest[..n]);
            rest = &rest[n..];
        }
    }

    /// Parameter names parallel to [`TriadModel::params`], as `<effect-id>.<name>`
    /// (e.g. `"bias.x"`, `"misalignment.xy"`, `"warmup.tau_s"`). The names do not depend on the
    /// triad; the argument keeps the signature parallel to [`TriadModel::param_units`].
    pub fn param_names(&self, triad: Triad) -> Vec<String> {
        let _ = triad;
        self.effects()
            .iter()
            .flat_map(|e| {
                let id = e.kind().id();
                e.param_names()
                    .into_iter()
                    .map(move |n| format!("{id}.{n}"))
            })
            .collect()
    }

    /// Typed parameter identities parallel to [`TriadModel::params`] (names as in
    /// [`TriadModel::param_names`]).
    pub fn param_ids(&self) -> Vec<crate::ParamId> {
        self.effects()
            .iter()
            .flat_map(|e| {
                let kind = e.kind();
                e.param_names()
                    .into_iter()
                    .zip(e.param_roles())
                    .map(move |(n, role)| crate::ParamId {
                        effect: kind,
                        role,
                        name: format!("{}.{n}", kind.id()),
                    })
            })
            .collect()
    }

    /// Parameter units for `triad`, parallel to [`TriadModel::params`].
    pub fn param_units(&self, triad: Triad) -> Vec<String> {
        self.effects()
            .iter()
            .flat_map(|e| e.param_units(triad))
            .collect()
    }

    /// Standard errors parallel to [`TriadModel::params`]; `None` where an effect has none.
    pub fn std_errors(&self) -> Vec<Option<f64>> {
        self.effects()
            .iter()
            .flat_map(|e| match e.std_errors() {
                Some(se) => se.into_iter().map(Some).collect::<Vec<_>>(),
                None => vec![None; e.n_params()],
            })
            .collect()
    }

    /// Set (or with `None` clear) the standard errors of all present effects, in the layout of
    /// [`TriadModel::params`].
    pub fn set_std_errors(&mut self, se: Option<&[f64]>) {
        let mut rest = se.unwrap_or(&[]);
        for e in self.effects_mut() {
            match se {
                None => e.set_std_errors(None),
                Some(_) => {
                    let n = e.n_params().min(rest.len());
                    e.set_std_errors(Some(rest[..n].to_vec()));
                    rest = &rest[n..];
                }
            }
        }
    }

    /// Validate every present effect, the noise and the residual RMS for `triad`. Keys in the
    /// error are relative to the triad table (e.g. `"scale-nonlinearity.cubic[1]"`).
    pub fn validate(&self, triad: Triad) -> Result<(), InvalidParam> {
        self.validate_effects(triad)?;
        if let Some(n) = &self.noise {
            n.validate().map_err(|e| e.within("noise"))?;
        }
        if let Some(r) = &self.residual_rms {
            check_finite("residual-rms", r)?;
            if r.iter().any(|v| *v < 0.0) {
                return Err(InvalidParam::new(
                    "residual-rms",
                    "an RMS is >= 0".to_string(),
                ));
            }
        }
        Ok(())
    }
}
