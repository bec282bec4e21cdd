//! imu-model: units, sample types, the library of physical MEMS IMU error effects (forward and
//! exact inverse), noise models and the calibration file format.
//!
//! One library of error effects is shared by the simulator (forward: true input ->
//! measurement), the fitting tools (flat parameter vectors with names and units) and the daemon
//! (exact inverse: measurement -> true input, for every sample). No device I/O, no async.
//!
//! # The model
//!
//! Each triad (accel in m/s^2, gyro in rad/s, mag in gauss; "U" below) has a [`TriadModel`]:
//! an optional instance of each effect, applied to the true input in the canonical order
//! ([`EffectKind::ALL`]). Following Aslan & Saranli (Eq. 1-2) the deterministic errors are bias
//! `B`, scale `S`, misalignment `M` and, for gyros, the g-dependent bias `B_g`; this crate adds
//! lever arm, asymmetric scale, nonlinearity, temperature and warm-up terms.
//!
//! | # | id (TOML table `[<triad>.<id>]`) | forward `x -> y` | fields (units) |
//! |---|---|---|---|
//! | 1 | `lever-arm` (accel only) | `x + w x (w x r) + a x r` | `offset-m` (m) |
//! | 2 | `misalignment` | `(I + M) x`, zero diagonal | `xy xz yx yz zx zy` (rad, omitted = 0) |
//! | 3 | `scale` | `x_i (1 + s_i)` | `value` (1) |
//! | 4 | `asymmetric-scale` | `x_i (1 + a_i sgn x_i)`, `abs(a) < 1` | `value` (1) |
//! | 5 | `temp-scale` | `x_i (1 + sum_k c_ki (T - T0)^k)` | `t0-c` (degC, default 25), `coefficients` (row k: 1/K^k) |
//! | 6 | `scale-nonlinearity` | `x + k2 x^2 + k3 x^3` per axis | `quadratic` (1/U), `cubic` (1/U^2) |
//! | 7 | `bias` | `x + b` | `value` (U) |
//! | 8 | `temp-bias` | `x + sum_k c_k (T - T0)^k` | `t0-c` (degC), `coefficients` (row k: U/K^k) |
//! | 9 | `warmup` | `x + A exp(-t / tau)` | `amplitude` (U), `tau-s` (s) |
//! | 10 | `g-sensitivity` (gyro only) | `x + G f` | `matrix` ((rad/s)/(m/s^2), row = gyro axis) |
//!
//! `w`, `a`, `f` are the TRUE angular rate, angular acceleration and specific force
//! ([`Conditions`]); `T` is the sensor temperature and `t` the time since power-on. Every effect
//! table also takes an optional `std-error` of the same shape as its parameters (an array for
//! single-field effects, a table with the same keys otherwise). Per triad there are also
//! `[<triad>.noise]` ([`NoiseModel`]: `white-density` U/sqrt(Hz), `bias-instability` U,
//! `bias-instability-tau-max-s` s, `random-walk` U/sqrt(s), `quantization-lsb` U) and
//! `residual-rms = [x, y, z]` (U) directly in `[<triad>]`. Misalignment entries are
//! dimensionless small angles: `M[row][col]` is the fraction of true axis `col` seen by sensor
//! axis `row`.
//!
//! # Canonical order, and why
//!
//! The order follows the signal through the sensor. The lever arm comes first because it
//! changes the physical input (the proof mass really feels that acceleration). Misalignment
//! then projects the true vector onto the non-orthogonal sensing axes, so every per-axis effect
//! that follows (scale, asymmetry, temperature scale, nonlinearity) acts on what each axis
//! actually senses. Gain effects precede the offsets: a bias is added after the gain stage, so
//! its value is directly the output at zero input and it does not get scaled by `S`. The
//! environmental offsets (temperature, warm-up, g-sensitivity) come last for the same reason:
//! their coefficients are in output units, as they are measured. With every effect small this
//! matches the paper's linearised `delta = B + S x + M x` to first order; the order matters for
//! the exact inverse, which undoes the stages in reverse.
//!
//! # Exact inverse
//!
//! [`TriadModel::inverse`] undoes the stages in reverse order; each stage inverse is exact
//! (closed form, a 3x3 LU solve for misalignment, a bracketed Newton iteration for the
//! nonlinearity, closed form when it has no cubic term). [`Calibration::correct_iterative`] additionally solves the accel/gyro coupling
//! (the lever arm needs the true rate, g-sensitivity the true specific force) by fixed-point
//! iteration. [`Calibration::correct`], what the daemon runs per sample, evaluates the same
//! inverse prepared once per calibration (`src/prepared.rs`): the gain inverse
//! `(I + M)^-1 D^-1` precomputed, and when every effect is linear and lever arm and
//! g-sensitivity are not both present, one affine map per triad with no iteration at all
//! ([`InversePath`]). Validation guarantees invertibility over [`Triad::validation_range`]: accel
//! +/-20 g, gyro +/-35 rad/s, mag +/-8 gauss (nonlinearity gain >= 0.5, misalignment entries
//! < 0.25 rad, `abs(s) < 1`, temperature scale within (0.5, 2) over -40..85 degC).
//!
//! # Files
//!
//! [`Calibration::from_toml_str`] / [`Calibration::load`] parse the strict TOML format
//! (`format = "imud-calibration/1"`, kebab-case keys, unknown keys rejected) and report
//! `file:line:column` with the key path; [`Calibration::to_toml_string`] writes a `# units:`
//! comment under every effect table. See `config/models/` for documented examples.
//!
//! # Example
//!
//! ```
//! use imu_model::{Calibration, Conditions, TrueMotion, Vec3};
//!
//! let text = r#"
//! format = "imud-calibration/1"
//! [gyro.bias]
//! value = [0.01, 0.0, -0.02]            # rad/s
//! [gyro.g-sensitivity]
//! matrix = [[0.0, 0.0, 2e-5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]  # (rad/s)/(m/s^2)
//! "#;
//! let cal = Calibration::from_toml_str(text, "example.toml")?;
//! let truth = TrueMotion {
//!     specific_force_m_s2: Vec3::new(0.0, 0.0, 9.80665),
//!     angular_rate_rad_s: Vec3::new(0.1, 0.0, 0.0),
//!     ..Default::default()
//! };
//! let c = Conditions::default();
//! let measured = cal.forward(&truth, &c);
//! let corrected = cal.correct(&measured, c.temp_c, c.time_since_power_on_s, Vec3::zeros());
//! assert!(corrected.converged);
//! assert!((corrected.gyro_rad_s - truth.angular_rate_rad_s).norm() < 1e-15);
//! # Ok::<(), imu_model::ModelError>(())
//! ```
//!
//! # Adding an effect (checklist)
//!
//! 1. Write `src/effects/<name>.rs` with a serde struct (`deny_unknown_fields`,
//!    `rename_all = "kebab-case"`, optional `std_error` of the same shape) implementing
//!    [`Effect`] (forward, exact inverse, flat params with names and units) and [`EffectDef`]
//!    (`ID` = the module name in kebab case, `DESCRIPTION`, `applies_to`, `neutral`,
//!    `field_units`, `validate`). Start the file with a `//!` line; state units in the docs.
//! 2. Add `<name>::<Type>,` to `register_effects!` in `src/effects/mod.rs` at its place in the
//!    canonical order. That generates the [`EffectKind`] variant, the [`TriadModel`] field, the
//!    TOML table and the registry plumbing.
//! 3. Give the new effect a random realistic parameter generator in the crate tests
//!    (`tests/common/mod.rs`, `random_params`): the exhaustive subset tests then cover it.
//! 4. Document the fields in the table above and, if useful, in `config/models/`.

pub use nalgebra;

/// A 3-vector of f64 (sensor frame unless stated otherwise).
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3x3 matrix of f64.
pub type Mat3 = nalgebra::Matrix3<f64>;

/// The shipped example error model of a 3DM-GX1-class unit (`config/models/example-3dm-gx1.toml`),
/// built in: the truth of `imud --sim`'s simulated device, and the default units of the Python
/// package's simulated fleet (`imud.example_model_toml()`), wherever they run.
pub const EXAMPLE_GX1_MODEL_TOML: &str =
    include_str!("../../../config/models/example-3dm-gx1.toml");

pub mod earth;
mod param;
pub mod units;

mod calibration;
mod effect;
pub mod effects;
mod error;
mod noise;
mod prepared;
mod sample;
mod triad;
mod triad_model;

pub use calibration::{
    CALIBRATION_FORMAT, COUPLING_TOLERANCE, Calibration, IN_MEMORY, InputFile,
    MAX_COUPLING_ITERATIONS, Provenance,
};
pub use effect::{Effect, EffectDef, InvalidParam};
pub use effects::misalignment::OffDiagonal;
pub use effects::scale_nonlinearity::NonlinearityStdError;
pub use effects::warmup::WarmupStdError;
pub use effects::{
    AsymmetricScale, Bias, EffectKind, GSensitivity, LeverArm, Misalignment, Scale,
    ScaleNonlinearity, TempBias, TempScale, TriadModel, Warmup,
};
pub use error::{ModelError, did_you_mean, line_col, line_of_key};
pub use noise::{
    BIAS_INSTABILITY_ADEV_FACTOR, DEFAULT_BIAS_INSTABILITY_TAU_MAX_S, NoiseGenerator, NoiseModel,
};
pub use param::{ParamId, ParamRole};
pub use prepared::{InversePath, SealedCalibration};
pub use sample::{Conditions, Corrected, Measured, TrueMotion};
pub use triad::Triad;
