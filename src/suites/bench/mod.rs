//! Benchmarks, one file each: render times per scene and backend
//! (`scenes`, `glint bench`, `cargo bench`), the hard-case suite's counts
//! and what the robust methods cost (`hard`, `glint bench hard`), the
//! specialised shader against the generic one (`specialize`, `glint bench
//! specialize`), glint against an Embree renderer of the same spec
//! (`embree`, `glint bench embree`), and what each sampler's error and time
//! come to (`samplers`, `glint bench samplers`), and what a scene costs
//! before its first ray against Embree's build (`build`, `glint bench build`). `process` times the glint
//! binary end to end for `glint bench`'s last column. `glint accuracy` (src/accuracy.rs)
//! measures error against time.

mod build;
mod common;
mod embree;
mod hard;
mod load;
mod process;
mod samplers;
mod scenes;
mod specialize;

pub use build::{run_build, BuildOptions, BuildReport, BuildRow};
pub use common::{default_scenes, Stat, CLASSIC_DIR, CLASSIC_SCENES};
pub use embree::{
    parse_result, run_embree, run_harness, EmbreeOptions, EmbreeReport, EmbreeScene, HarnessRun,
    Mode,
};
pub use hard::{run_hard, HardOptions, HardReport};
pub use load::{run_load, LoadOptions, LoadReport, LoadRow};
pub use samplers::{run_samplers, sampler_scenes, SamplerRow, SamplersOptions, SamplersReport};
pub use scenes::{run, BenchOptions, BenchReport, SceneResult};
pub use specialize::{run_specialize, specialize_scenes, SpecializeOptions};
