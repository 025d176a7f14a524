//! A render on the CPU reference: its memory checked first, cancelled
//! renders asked once a band (a whole image asks no pixel whether it is
//! kept), its rays and threads' CPU time counted.

use std::time::Instant;

use super::options::PixelFormat;
use super::region::Region;
use super::renderer::{Prepared, Renderer};
use crate::cpu::{self, Keep, Out, Precision};
use crate::images::framebuffer::Image;
use crate::memory::{self, MemoryNeed};
use crate::scene::Scene;
use crate::timing::Timings;
use crate::Error;

impl Renderer {
    /// `region` of the scene on the CPU reference, as `pixels` asks.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn render_on_cpu(
        &self,
        scene: &Scene,
        p: &Prepared,
        geometry: &cpu::Geometry,
        precision: Precision,
        region: Region,
        pixels: PixelFormat,
        progress: &(dyn Fn(u64, u64) + Sync),
        timings: &mut Timings,
        need: &mut MemoryNeed,
    ) -> Result<Image, Error> {
        let out = match pixels {
            PixelFormat::Float => Out::Float,
            // 8-bit pixels are made band by band in the render's threads,
            // as the GPU packs them on the device: the float image is
            // never whole.
            PixelFormat::Rgb8 => {
                *need = MemoryNeed::rgb8(p.camera.width, p.camera.height);
                Out::Rgb8
            }
        };
        need.check(memory::available())?;
        let start = Instant::now();
        // Cancelled, the bands left trace nothing.
        let cancelled = || self.cancelled();
        let keeps = |x, y| region.keeps(x, y) && !self.cancelled();
        let keep = match region {
            Region::All => Keep::All(&cancelled),
            _ => Keep::Where(&keeps),
        };
        let (image, work) = cpu::render_rows(
            scene,
            &p.bvh,
            geometry,
            &p.camera,
            &self.cpu_options(p, precision),
            region.rows(p.camera.height),
            keep,
            progress,
            out,
        );
        if self.cancelled() {
            return Err(Error::Cancelled);
        }
        timings.add("cpu render", start.elapsed());
        timings.count(crate::timing::CLOSEST_RAYS, work.rays[0]);
        timings.count(crate::timing::SHADOW_RAYS, work.rays[1]);
        timings.count(crate::timing::UNTRACED_SHADOW_RAYS, work.untraced);
        if let Some(t) = work.cpu_time {
            timings.count(crate::timing::CPU_TIME_NS, t.as_nanos() as u64);
        }
        Ok(image)
    }
}
