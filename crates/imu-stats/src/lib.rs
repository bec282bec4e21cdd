//! Numerics with no IMU knowledge, the lowest layer of the analyses: the one least-squares
//! engine ([`lsq`]), distribution functions ([`distributions`], from statrs), descriptive
//! statistics ([`descriptive`]), linear least squares ([`linear`]), spectra ([`spectral`],
//! rustfft), the Allan family of deviations ([`allan`]) and the IEEE noise-term fit of an
//! Allan curve ([`noise_terms`]).
//!
//! Layering: this crate depends on no `imu-*` crate (Cargo enforces it); `imu-model` and
//! `imu-analysis` build on it.

pub mod allan;
pub mod descriptive;
pub mod distributions;
pub mod linear;
pub mod lsq;
pub mod noise_terms;
pub mod spectral;
