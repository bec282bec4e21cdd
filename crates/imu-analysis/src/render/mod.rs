//! What the clients show a person: small self-contained SVG charts (`svg`, a leaf that knows
//! nothing of IMUs; the analyses build their charts with it) and the HTML report pages (`html`,
//! the top of the crate: it renders workbench, ladder and characterisation results).
//! `figure` draws small multiples (panels sharing their axes, caller-chosen colours) on `svg`'s
//! axes; `allan` builds imu-noise's figures with them; `lint` checks any rendered SVG (texts
//! inside the view box, no overlaps, finite numbers) for the tests; `number` is the one number
//! format of every page and text summary (a leaf).

pub mod allan;
pub mod figure;
pub mod html;
pub mod lint;
pub mod number;
pub mod svg;
