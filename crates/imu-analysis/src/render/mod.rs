//! What the clients show a person: small self-contained SVG charts (`svg`, a leaf that knows
//! nothing of IMUs; the analyses build their charts with it) and the HTML report pages (`html`,
//! the top of the crate: it renders workbench, ladder and characterisation results), and
//! `number`, the one number format of every page and text summary (a leaf).

pub mod html;
pub mod number;
pub mod svg;
