//! What glint measures and checks itself with, one module a command:
//! `accuracy` (error against time), `bench` (speed, against Embree too),
//! `check` (is a device rendering right?) and `hard` (the hard cases), and
//! `plot`, the charts they draw.

pub mod accuracy;
pub mod bench;
pub mod check;
pub mod hard;
#[cfg(feature = "plots")]
pub mod plot;
