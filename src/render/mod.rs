//! Rendering a parsed scene with a chosen backend: the library's front door.
//!
//! - `job` and `sink`: a render as one value (what to render, when to
//!   stop) and where its image goes; `run` carries it out in one call
//!   (`Renderer::run`), `frames` an animation's frames.
//! - `renderer`: the `Renderer`, a backend set up once, and what it does
//!   below a job (made-ready scenes, probes, a pixel's path).
//! - `options`, `output`: what a render is asked for and what it gives back.
//! - `passes` and `progressive`: renders in sample passes until an error or
//!   a time, adaptive blocks.
//! - `region`: which pixels a render computes.
//! - `on_cpu`: a render on the CPU reference.
//! - `probes`: below a render, every pixel's hits and verdicts, or one
//!   pixel's path.

mod frames;
mod job;
mod motion;
mod on_cpu;
mod options;
mod output;
pub mod passes;
mod probes;
mod progressive;
mod region;
mod renderer;
mod run;
mod sink;

pub use job::{settings_text, Done, Frames, FramesDone, Job, Passes, Quiet, Stop, Target, Watch};
pub use options::{Backend, PixelFormat, RenderOptions};
pub use output::RenderOutput;
pub use probes::{pixel_path, probe, Probed};
pub use renderer::{render, PreparedScene, Renderer};
pub use run::run;
pub use sink::Sink;
