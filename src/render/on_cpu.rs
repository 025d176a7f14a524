//! A render on the CPU reference, and a JPEG encoded as it is rendered: each
//! strip of the file's rows is encoded on the thread that finished its
//! rows, while the others go on rendering, so that after the last row only
//! one strip's encode and the join remain (`cpu::Out::Rgb8Strips`).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use super::options::PixelFormat;
use super::region::Region;
use super::renderer::{Prepared, Renderer};
use crate::cpu::{self, Keep, Out, Precision};
use crate::images::encode::jpeg::Strips;
use crate::images::framebuffer::Image;
use crate::memory::{self, MemoryNeed};
use crate::scene::Scene;
use crate::timing::Timings;
use crate::Error;

impl Renderer {
    /// `region` of the scene on the CPU reference, as `pixels` asks; with
    /// the JPEG's bytes where it asks for a JPEG.
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
    ) -> Result<(Image, Option<Vec<u8>>), Error> {
        let (w, h) = (p.camera.width, p.camera.height);
        if pixels != PixelFormat::Float {
            // The bands become bytes as they are rendered.
            *need = MemoryNeed::rgb8(w, h);
        }
        need.check(memory::available())?;
        let strips = match (pixels, &region) {
            (PixelFormat::Jpeg(quality), Region::All) => {
                Some(Strips::new(w, h, quality).map_err(|e| {
                    Error::InvalidOption(format!("{e}: write .png, .ppm or .exr instead"))
                })?)
            }
            _ => None,
        };
        let parts = Mutex::new(Vec::new());
        let encode_ns = AtomicU64::new(0);
        let take = |y0: u32, rgb: &[u8]| {
            let Some(strips) = &strips else { return };
            if self.cancelled() {
                return;
            }
            let started = crate::timing::thread_cpu_time();
            let part = strips.encode(rgb);
            if let (Some(a), Some(b)) = (started, crate::timing::thread_cpu_time()) {
                let ns = b.saturating_sub(a).as_nanos() as u64;
                encode_ns.fetch_add(ns, Ordering::Relaxed);
            }
            let index = (y0 / strips.rows()) as usize;
            parts
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push((index, part));
        };
        let out = match (pixels, &strips) {
            (PixelFormat::Float, _) => Out::Float,
            (_, Some(strips)) => Out::Rgb8Strips {
                rows: strips.rows(),
                strip: &take,
            },
            (_, None) => Out::Rgb8,
        };
        let start = Instant::now();
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
            region.rows(h),
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
        if let Some(t) = work.cpu_time {
            timings.count(crate::timing::CPU_TIME_NS, t.as_nanos() as u64);
        }
        let encoded = match (pixels, strips) {
            (PixelFormat::Jpeg(_), Some(strips)) => {
                let mut parts = parts.into_inner().unwrap_or_else(|e| e.into_inner());
                parts.sort_unstable_by_key(|(i, _)| *i);
                let parts = parts.into_iter().map(|(_, p)| p).collect::<Result<_, _>>();
                let bytes = timings.time("encode", || strips.join(parts?));
                if work.cpu_time.is_some() {
                    timings.count(crate::timing::ENCODE_CPU_NS, encode_ns.into_inner());
                }
                Some(bytes.map_err(|reason| Error::Encode {
                    format: "JPEG",
                    reason,
                })?)
            }
            (PixelFormat::Jpeg(quality), None) => {
                Some(super::output::encode_jpeg(&image, quality, timings)?)
            }
            _ => None,
        };
        Ok((image, encoded))
    }
}
