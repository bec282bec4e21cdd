//! Misalignment / cross-coupling (the paper's M_A, M_G): each sensing axis also picks up a small
//! fraction of the other two axes' input because the axes are not exactly orthogonal.

use crate::effect::{Effect, EffectDef, InvalidParam, check_finite, check_std_errors, fill};
use crate::{Conditions, EffectKind, Mat3, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Off-diagonal matrix entries by (row, column) name; absent entries are 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct OffDiagonal {
    /// Row x, column y.
    #[serde(default)]
    pub xy: f64,
    /// Row x, column z.
    #[serde(default)]
    pub xz: f64,
    /// Row y, column x.
    #[serde(default)]
    pub yx: f64,
    /// Row y, column z.
    #[serde(default)]
    pub yz: f64,
    /// Row z, column x.
    #[serde(default)]
    pub zx: f64,
    /// Row z, column y.
    #[serde(default)]
    pub zy: f64,
}

impl OffDiagonal {
    fn to_vec(self) -> Vec<f64> {
        vec![self.xy, self.xz, self.yx, self.yz, self.zx, self.zy]
    }
    fn from_slice(p: &[f64]) -> Self {
        let mut a = [0.0; 6];
        fill(&mut a, p);
        OffDiagonal {
            xy: a[0],
            xz: a[1],
            yx: a[2],
            yz: a[3],
            zx: a[4],
            zy: a[5],
        }
    }
}

/// Misalignment. Forward: `y = (I + M) x`, `M` with zero diagonal; `M[row][col]` is how much
/// of true input axis `col` appears on sensor axis `row` (small-angle, rad).
///
/// TOML `[<triad>.misalignment]`: `xy`, `xz`, `yx`, `yz`, `zx`, `zy` (rad, omitted = 0),
/// optional `std-error = { xy = ..., ... }` (rad).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Misalignment {
    /// `M[x][y]`, rad.
    #[serde(default)]
    pub xy: f64,
    /// `M[x][z]`, rad.
    #[serde(default)]
    pub xz: f64,
    /// `M[y][x]`, rad.
    #[serde(default)]
    pub yx: f64,
    /// `M[y][z]`, rad.
    #[serde(default)]
    pub yz: f64,
    /// `M[z][x]`, rad.
    #[serde(default)]
    pub zx: f64,
    /// `M[z][y]`, rad.
    #[serde(default)]
    pub zy: f64,
    /// One-sigma standard errors, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<OffDiagonal>,
}

/// Largest accepted |entry|: keeps every row of I + M strictly diagonally dominant (row sum of
/// off-diagonals < 0.5), so I + M is always invertible and well conditioned.
pub const MAX_ABS_RAD: f64 = 0.25;

impl Misalignment {
    /// `I + M`.
    pub fn matrix(&self) -> Mat3 {
        Mat3::new(
            1.0, self.xy, self.xz, //
            self.yx, 1.0, self.yz, //
            self.zx, self.zy, 1.0,
        )
    }
    fn entries(&self) -> [f64; 6] {
        [self.xy, self.xz, self.yx, self.yz, self.zx, self.zy]
    }
}

const NAMES: [&str; 6] = ["xy", "xz", "yx", "yz", "zx", "zy"];

impl Effect for Misalignment {
    fn kind(&self) -> EffectKind {
        EffectKind::Misalignment
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        NAMES
            .iter()
            .map(|n| {
                let b = n.as_bytes();
                let axis = |c: u8| usize::from(c - b'x');
                ParamRole::Coupling {
                    row: axis(b[0]),
                    col: axis(b[1]),
                }
            })
            .collect()
    }
    fn param_names(&self) -> Vec<String> {
        NAMES.iter().map(|s| s.to_string()).collect()
    }
    fn param_units(&self, _triad: Triad) -> Vec<String> {
        vec!["rad".to_string(); 6]
    }
    fn params(&self) -> Vec<f64> {
        self.entries().to_vec()
    }
    fn set_params(&mut self, p: &[f64]) {
        let o = OffDiagonal::from_slice(p);
        (self.xy, self.xz, self.yx, self.yz, self.zx, self.zy) = (o.xy, o.xz, o.yx, o.yz, o.zx, o.zy);
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.std_error.map(|s| s.to_vec())
    }
    fn set_std_errors(&mut self, se: Option<Vec<f64>>) {
        self.std_error = se.map(|s| OffDiagonal::from_slice(&s));
    }
    fn forward(&self, x: Vec3, _c: &Conditions) -> Vec3 {
        self.matrix() * x
    }
    fn inverse(&self, y: Vec3, _c: &Conditions) -> Vec3 {
        // Validation guarantees I + M is non-singular; NaN flags a hand-built singular model
        // rather than panicking on the daemon's path.
        self.matrix()
            .lu()
            .solve(&y)
            .unwrap_or_else(|| Vec3::repeat(f64::NAN))
    }
    fn inverse_batch(&self, ys: &mut [Vec3], _c: &Conditions) {
        // One factorisation for the batch; each solve is the one `inverse` makes.
        let lu = self.matrix().lu();
        for y in ys {
            *y = lu.solve(y).unwrap_or_else(|| Vec3::repeat(f64::NAN));
        }
    }
}

impl EffectDef for Misalignment {
    const ID: &'static str = "misalignment";
    const DESCRIPTION: &'static str = "axis misalignment / cross-coupling: each axis senses a small fraction of the other axes' input, y = (I + M) x (paper Eq. 1-2, M_A and M_G)";
    const GAIN: bool = true;
    fn neutral() -> Self {
        Misalignment::default()
    }
    fn field_units(_triad: Triad) -> Vec<(&'static str, String)> {
        vec![("xy, xz, yx, yz, zx, zy", "rad".to_string())]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        for (name, v) in NAMES.iter().zip(self.entries()) {
            check_finite(name, &[v])?;
            if v.abs() >= MAX_ABS_RAD {
                return Err(InvalidParam::new(
                    *name,
                    format!(
                        "|{v}| rad is not a small misalignment (must be < {MAX_ABS_RAD}); values are in radians"
                    ),
                ));
            }
        }
        if let Some(se) = &self.std_error {
            check_std_errors("std-error", &se.to_vec())?;
        }
        Ok(())
    }
}
