//! Render settings: what a scene file asks for (extension directives such as
//! `spp: 16`), what the command line overrides, and the resolved values.

/// Settings as written in a scene file or given on the command line; `None`
/// leaves the choice to the next source (file, then built-in default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Settings {
    /// Most reflection bounces; 0 renders without reflection.
    pub reflect: Option<u32>,
    /// Primary samples per pixel (antialiasing, motion blur).
    pub spp: Option<u32>,
    /// Shadow rays per area light per shaded point.
    pub shadow_samples: Option<u32>,
    /// Fraction of the frame interval the shutter is open, in [0, 1].
    pub shutter: Option<f64>,
    /// Seed of every random number the renderer draws.
    pub seed: Option<u32>,
    /// Frames per second of `--frames` animations.
    pub fps: Option<f64>,
    /// How the random dimensions are sampled.
    pub sampler: Option<Sampler>,
}

impl Settings {
    /// `self`'s values where given, else `base`'s.
    pub fn or(self, base: Settings) -> Settings {
        Settings {
            reflect: self.reflect.or(base.reflect),
            spp: self.spp.or(base.spp),
            shadow_samples: self.shadow_samples.or(base.shadow_samples),
            shutter: self.shutter.or(base.shutter),
            seed: self.seed.or(base.seed),
            fps: self.fps.or(base.fps),
            sampler: self.sampler.or(base.sampler),
        }
    }
}

/// Resolved settings: what the renderer simulates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effects {
    /// Reflection bounces after the primary hit (0: none).
    pub reflect_depth: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Shadow samples per area light.
    pub shadow_samples: u32,
    /// Fraction of the frame interval the shutter is open.
    pub shutter: f64,
    /// Seed of the per-pixel sample hash.
    pub seed: u32,
    /// Frames per second of an animation (the shutter's time base).
    pub fps: f64,
    /// How the pixel position, the time and area lights' points are drawn.
    pub sampler: Sampler,
}

impl Default for Effects {
    fn default() -> Self {
        Effects::resolve(&Settings::default())
    }
}

impl Effects {
    /// Area lights get this many shadow rays unless told otherwise: enough
    /// for a penumbra without visible banding at one sample per pixel.
    pub const DEFAULT_SHADOW_SAMPLES: u32 = 16;
    /// Frames per second unless the scene or `--fps` says otherwise.
    pub const DEFAULT_FPS: f64 = 24.0;
    /// Most reflection bounces a scene may ask for.
    pub const MAX_REFLECT: u32 = 64;
    /// Most samples per pixel a scene may ask for.
    pub const MAX_SPP: u32 = 65_536;
    /// Most shadow samples per area light a scene may ask for.
    pub const MAX_SHADOW_SAMPLES: u32 = 4096;

    /// The settings with every unset value at its default.
    pub fn resolve(s: &Settings) -> Effects {
        Effects {
            reflect_depth: s.reflect.unwrap_or(0),
            spp: s.spp.unwrap_or(1),
            shadow_samples: s.shadow_samples.unwrap_or(Self::DEFAULT_SHADOW_SAMPLES),
            shutter: s.shutter.unwrap_or(0.0),
            seed: s.seed.unwrap_or(0),
            fps: s.fps.unwrap_or(Self::DEFAULT_FPS),
            sampler: s.sampler.unwrap_or_default(),
        }
    }

    /// How long the shutter stays open, in seconds.
    pub fn shutter_seconds(&self) -> f64 {
        self.shutter / self.fps
    }

    /// Scene time of frame `index`, in seconds.
    pub fn frame_time(&self, index: u32) -> f64 {
        f64::from(index) / self.fps
    }
}

/// How a pixel's samples draw their random dimensions: the position in the
/// pixel, the time in the shutter, and each area light's point (per bounce).
/// Both are unbiased and give the same image on every device for a seed;
/// they differ in how evenly a pixel's samples cover each dimension
/// (docs/effects.md, "Samplers").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Sampler {
    /// Owen-scrambled Sobol points (Burley 2020), a new randomisation per
    /// pixel and dimension: every power-of-two prefix of a pixel's samples
    /// is stratified in each 2D dimension at once, at every scale.
    #[default]
    Sobol,
    /// A jittered grid per dimension (`cols x rows`, visited from a random
    /// cell) and a uniform random time: glint's sampler before `sobol`, its
    /// images bit for bit.
    Stratified,
}

impl Sampler {
    /// Every sampler, the default first.
    pub const ALL: [Sampler; 2] = [Sampler::Sobol, Sampler::Stratified];

    /// What scene files, flags and reports call it.
    pub fn name(self) -> &'static str {
        match self {
            Sampler::Sobol => "sobol",
            Sampler::Stratified => "stratified",
        }
    }

    /// The sampler called `name` (in any case, as the scene format's
    /// words); None for any other name.
    pub fn from_name(name: &str) -> Option<Sampler> {
        Sampler::ALL
            .into_iter()
            .find(|s| s.name().eq_ignore_ascii_case(name))
    }
}

impl std::fmt::Display for Sampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
