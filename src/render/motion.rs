//! An animation's moving scene from frame to frame: the first frame builds
//! the tree and packs the scene as any render does; each later frame moves
//! the same primitives, so it refits that tree (`Bvh::refit`) and moves the
//! packed geometry in place instead, and builds afresh only where refitting
//! cannot serve: another render scale, or a tree whose SAH cost has grown
//! past `REFIT_LIMIT` times what it was when built.

use super::options::PixelFormat;
use super::output::RenderOutput;
use super::region::Region;
use super::renderer::{Packed, Prepared, Renderer};
use crate::bvh::refit::REFIT_LIMIT;
use crate::scene::Scene;
use crate::Error;

/// The last frame's tree and packing, and the SAH cost the tree had when
/// it was built.
pub(super) struct Moving {
    /// The scene at the last frame's time, in view space: the next frame
    /// is written over it.
    view: Scene,
    prepared: Prepared,
    packed: Packed,
    built_cost: f64,
}

impl Renderer {
    /// Frame `scene` at `time` seconds, from what the frame before left in
    /// `moving` where there is one (and leaving this frame's there).
    /// `-v` shows `move` (the scene at that time, in view space), then a
    /// refitted frame's `refit` phase where a built one shows `bvh`.
    pub(super) fn render_moving_frame(
        &self,
        scene: &Scene,
        time: f64,
        moving: &mut Option<Moving>,
        pixels: PixelFormat,
    ) -> Result<RenderOutput, Error> {
        let mut timings = self.take_setup_timings();
        let mut last = moving.take();
        let mut view = last
            .as_mut()
            .map(|m| std::mem::take(&mut m.view))
            .unwrap_or_default();
        timings.time("move", || scene.at_time_in_view_space_into(time, &mut view));
        let refitted = last.and_then(|mut m| {
            let bvh = &mut m.prepared.bvh;
            let fits = timings.time("refit", || {
                bvh.refit_for_render(&view, &m.prepared.effects)
                    && bvh.stats().sah_cost <= REFIT_LIMIT * m.built_cost
            });
            fits.then_some(m)
        });
        let mut m = match refitted {
            Some(mut m) => {
                let bvh = &m.prepared.bvh;
                timings.time("pack", || match &mut m.packed {
                    Packed::Cpu(geometry) => geometry.refit(&view, bvh),
                    // Its upload sends only the lists that changed.
                    Packed::Gpu(packed) => packed.refit(&view, bvh),
                });
                m
            }
            None => {
                let prepared = self.prepare(&view, &mut timings);
                let packed = self.pack(&view, &prepared, &mut timings);
                Moving {
                    view: Scene::default(),
                    built_cost: prepared.bvh.stats().sah_cost,
                    prepared,
                    packed,
                }
            }
        };
        m.view = view;
        let m = moving.insert(m);
        self.render_prepared_as(
            &m.view,
            &m.prepared,
            &m.packed,
            timings,
            Region::All,
            pixels,
            &|_, _| {},
        )
    }
}
