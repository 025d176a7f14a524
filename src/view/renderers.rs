//! The renderers the window keeps (each with its device, pipelines and
//! buffers), one per backend and size, for views and for their previews;
//! and the GPU tile that keeps a view change answered quickly.

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use crate::cpu::Precision;
use crate::gpu::Context;
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::{Scene, Settings};
use crate::Error;

/// A view change should be answered within this. A Vulkan device ends a
/// cancelled render only when its tiles in flight finish, so where one
/// took longer (a slow device, a heavy scene) the window's GPU renders
/// move to smaller tiles (`view_tile`), unless `--tile` was given.
pub const ANSWER_WITHIN: Duration = Duration::from_millis(100);

/// The smallest tile the window moves to: on lavapipe (2 cores,
/// `soft_shadows`, 640x480, 2026-12-05) a cancelled render ended 4-30 ms
/// after the flag at tiles of 64, 51-137 ms at 128 and 0.5-1.7 s at 512,
/// and passes were no slower at 64; below that each tile's fixed cost
/// (a submit and a wait) grows against its pixels.
const SMALLEST_VIEW_TILE: u32 = 64;

/// The tile edge, from `edge`, whose tiles in flight should end within
/// half of `ANSWER_WITHIN`, where a cancelled render at `edge` took
/// `answered_in`: a tile's time grows with its area.
fn view_tile(edge: u32, answered_in: Duration) -> u32 {
    if answered_in <= ANSWER_WITHIN {
        return edge;
    }
    let scale = (ANSWER_WITHIN.as_secs_f64() / 2.0 / answered_in.as_secs_f64()).sqrt();
    let mut tile = edge;
    while tile > SMALLEST_VIEW_TILE && f64::from(tile) > f64::from(edge) * scale {
        tile /= 2;
    }
    tile.min(edge)
}

/// Which renderer: a backend at a size, for the view or for its preview.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct Key {
    pub(super) backend: Backend,
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) preview: bool,
}

/// The renderers made so far (each keeps its device, pipelines and
/// buffers), all ending their renders on `control.cancel`.
pub(super) struct Renderers {
    made: HashMap<Key, Renderer>,
    options: RenderOptions,
    cancel: Arc<AtomicBool>,
    /// The GPU tile the window moved to (`view_tile`), if it did.
    tile: Option<u32>,
    /// The device that presents to the window (`device::Screen`): every
    /// GPU renderer is made on it.
    context: Option<Context>,
}

impl Renderers {
    pub(super) fn new(options: RenderOptions, cancel: Arc<AtomicBool>) -> Renderers {
        Renderers {
            made: HashMap::new(),
            options,
            cancel,
            tile: None,
            context: None,
        }
    }

    /// GPU renderers made from now on run on `ctx`.
    pub(super) fn use_context(&mut self, ctx: Context) {
        self.context = Some(ctx);
    }

    pub(super) fn options(&self) -> &RenderOptions {
        &self.options
    }

    pub(super) fn make(&mut self, key: Key) -> Result<(), Error> {
        if self.made.contains_key(&key) {
            return Ok(());
        }
        let cpu = key.backend == Backend::Cpu;
        let o = &self.options;
        let options = RenderOptions {
            width: key.width,
            height: key.height,
            backend: key.backend,
            precision: if cpu { Precision::F32 } else { o.precision },
            device: if cpu { None } else { o.device.clone() },
            settings: if key.preview {
                preview_settings(o.settings)
            } else {
                o.settings
            },
            tile: o.tile.or(self.tile),
            // Every view change is a new view, so a new tree: kept, each
            // would be an entry nothing reads again (the scene itself was
            // read through the cache before the window opened).
            scene_cache: None,
            ..o.clone()
        };
        let mut r = match (&self.context, cpu) {
            (Some(ctx), false) => Renderer::on(&options, ctx.clone())?,
            _ => Renderer::new(&options)?,
        };
        r.set_cancel(self.cancel.clone());
        self.made.insert(key, r);
        Ok(())
    }

    pub(super) fn get(&self, key: Key) -> &Renderer {
        &self.made[&key]
    }

    /// Where tiles of `edge` keep a view change waiting `waits` (measured
    /// from a cancelled render, or a lower bound from the preview), later
    /// views' GPU renderers use smaller tiles (previews keep theirs: they
    /// are quick). Returns what to tell the user.
    fn fit_tiles(&mut self, edge: u32, waits: Duration, what: &str) -> Option<String> {
        if self.options.tile.is_some() {
            return None;
        }
        let tile = view_tile(edge, waits);
        if tile >= edge {
            return None;
        }
        self.tile = Some(tile);
        // Dropped now, so their device memory is free before the next.
        self.made.retain(|k, r| k.preview || !r.is_gpu());
        Some(format!(
            "{what} {:.0} ms with GPU tiles of {edge} px; the window now renders in tiles \
             of {tile} px (--tile sets them)",
            waits.as_secs_f64() * 1e3
        ))
    }

    /// `fit_tiles` after a render on `key` ended `answered_in` after it
    /// was told to.
    pub(super) fn answered(&mut self, key: Key, answered_in: Duration) -> Option<String> {
        let edge = self
            .made
            .get(&key)
            .filter(|r| r.is_gpu())?
            .options()
            .gpu
            .tile_size;
        self.fit_tiles(edge, answered_in, "a view change waited")
    }

    /// `fit_tiles` from the preview on `key` (a quarter of the pixels, the
    /// least work a pixel can take), which traced for `traced`: a full
    /// view's tile takes at least its share of that, and a cancelled
    /// render waits for the tiles in flight (two, where there are two).
    pub(super) fn previewed(
        &mut self,
        key: Key,
        traced: Duration,
        view: (u32, u32),
    ) -> Option<String> {
        let r = self.made.get(&key).filter(|r| r.is_gpu())?;
        let edge = self.tile.unwrap_or(r.options().gpu.tile_size);
        let tile = f64::from(edge.min(view.0)) * f64::from(edge.min(view.1));
        let share = tile / (f64::from(key.width) * f64::from(key.height)).max(1.0);
        let tiles = view.0.div_ceil(edge.max(1)) * view.1.div_ceil(edge.max(1));
        let in_flight = f64::from(tiles.clamp(1, 2));
        self.fit_tiles(
            edge,
            traced.mul_f64(in_flight * share),
            "the preview puts a view change's wait at least at",
        )
    }
}

/// `render --quick`'s settings, over whatever else was asked.
fn preview_settings(s: Settings) -> Settings {
    Settings {
        spp: Some(1),
        shadow_samples: Some(1),
        reflect: Some(0),
        ..s
    }
}

/// Whether a preview would be quicker than the view's first pass: the
/// scene asks for more than the preview simulates.
pub(super) fn heavier_than_preview(scene: &Scene, options: &RenderOptions) -> bool {
    let preview = RenderOptions {
        settings: preview_settings(options.settings),
        ..options.clone()
    };
    let (full, quick) = (options.effects(scene), preview.effects(scene));
    options.features(scene) != preview.features(scene)
        || (options.features(scene).area_lights && full.shadow_samples > quick.shadow_samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slow_answer_moves_to_tiles_whose_time_fits_the_bound() {
        let ms = Duration::from_millis;
        assert_eq!(view_tile(512, ms(80)), 512, "answered in time");
        assert_eq!(view_tile(512, ANSWER_WITHIN), 512);
        // 230 ms at 512: a tile of half the time needs sqrt(50/230) of the
        // edge, 239 px, so 128.
        assert_eq!(view_tile(512, ms(230)), 128);
        assert_eq!(view_tile(512, ms(120)), 256);
        assert_eq!(view_tile(512, ms(5000)), SMALLEST_VIEW_TILE);
        assert_eq!(view_tile(32, ms(5000)), 32, "never larger");
    }

    #[test]
    fn a_slow_gpu_answer_remakes_the_views_renderer_with_smaller_tiles() {
        let options = RenderOptions {
            width: 40,
            height: 30,
            backend: Backend::Gpu,
            ..RenderOptions::default()
        };
        let key = Key {
            backend: Backend::Gpu,
            width: 40,
            height: 30,
            preview: false,
        };
        let mut renderers = Renderers {
            made: HashMap::new(),
            options: options.clone(),
            cancel: Arc::new(AtomicBool::new(false)),
            tile: None,
            context: None,
        };
        if let Err(e) = renderers.make(key) {
            let ci = std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "false");
            assert!(!ci, "CI is set but no Vulkan device is usable: {e}");
            eprintln!("skipped: no Vulkan device ({e})");
            return;
        }
        let edge = renderers.get(key).options().gpu.tile_size;
        assert!(edge > SMALLEST_VIEW_TILE, "the profile's tile is {edge}");
        assert_eq!(renderers.answered(key, Duration::from_millis(20)), None);
        let note = renderers
            .answered(key, Duration::from_secs(2))
            .expect("a note");
        assert!(
            note.contains(&format!("waited 2000 ms with GPU tiles of {edge} px"))
                && note.contains(&format!("tiles of {SMALLEST_VIEW_TILE} px (--tile")),
            "{note}"
        );
        assert!(
            !renderers.made.contains_key(&key),
            "the old renderer is dropped"
        );
        renderers.make(key).expect("remade");
        assert_eq!(
            renderers.get(key).options().gpu.tile_size,
            SMALLEST_VIEW_TILE
        );

        // Before any view's pass: the preview's time gives a lower bound.
        let preview = Key {
            width: 20,
            height: 15,
            preview: true,
            ..key
        };
        let mut fresh = Renderers {
            made: HashMap::new(),
            options: options.clone(),
            cancel: Arc::new(AtomicBool::new(false)),
            tile: None,
            context: None,
        };
        fresh.make(preview).expect("preview made");
        // The view, 40x30, is one tile of 1,200 pixels, 4x the preview's.
        let ms = Duration::from_millis;
        assert_eq!(
            fresh.previewed(preview, ms(20), (40, 30)),
            None,
            "80 ms: in time"
        );
        let note = fresh.previewed(preview, ms(30), (40, 30)).expect("120 ms");
        assert!(note.contains("at least at 120 ms"), "{note}");
        assert!(
            fresh.made.contains_key(&preview),
            "the preview's renderer is kept"
        );
        fresh.make(key).expect("made");
        assert!(fresh.get(key).options().gpu.tile_size < edge);

        // --tile is the user's choice: kept.
        let mut chosen = Renderers {
            made: HashMap::new(),
            options: RenderOptions {
                tile: Some(256),
                ..options
            },
            cancel: Arc::new(AtomicBool::new(false)),
            tile: None,
            context: None,
        };
        chosen.make(key).expect("made");
        assert_eq!(chosen.answered(key, Duration::from_secs(2)), None);
        assert_eq!(chosen.get(key).options().gpu.tile_size, 256);
    }
}
