//! Encoding and writing images on worker threads while the next is
//! rendered: an animation's frame N is encoded and written while frame N+1
//! traces. The queue is bounded (a frame waits to be handed over while
//! every worker is busy), so memory holds at most a few frames whatever
//! the animation's length; a frame shared by several files (a scene where
//! nothing moves) is encoded once.

use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, SyncSender};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;
use std::time::Instant;

use crate::images::encode::{EncodeOptions, ImageFile};
use crate::images::framebuffer::{write_bytes, Image};
use crate::timing::Timings;
use crate::Error;

/// One image, encoded once however many files it goes to.
pub struct Encoded {
    image: Image,
    kind: ImageFile,
    options: EncodeOptions,
    bytes: OnceLock<Result<Vec<u8>, String>>,
}

impl Encoded {
    /// `image`, to be encoded as `kind` by the first writer that needs it.
    pub fn new(image: Image, kind: ImageFile, options: EncodeOptions) -> Arc<Encoded> {
        Arc::new(Encoded {
            image,
            kind,
            options,
            bytes: OnceLock::new(),
        })
    }
}

struct Task {
    frame: Arc<Encoded>,
    path: PathBuf,
}

/// Worker threads that encode and write what `push` hands them.
pub struct WriteQueue {
    sender: Option<SyncSender<Task>>,
    workers: Vec<JoinHandle<()>>,
    shared: Arc<Shared>,
}

#[derive(Default)]
struct Shared {
    /// The first failure; later tasks are dropped once it is set.
    error: Mutex<Option<Error>>,
    /// Time the workers spent encoding and writing, summed over them.
    timings: Mutex<Timings>,
}

impl WriteQueue {
    /// `workers` threads (at least one); `written(path)` is called on a
    /// worker after each file is in place.
    pub fn new(
        workers: usize,
        written: impl Fn(&std::path::Path) + Send + Sync + 'static,
    ) -> WriteQueue {
        let workers = workers.max(1);
        let (sender, receiver) = sync_channel::<Task>(workers);
        let receiver = Arc::new(Mutex::new(receiver));
        let shared = Arc::new(Shared::default());
        let written = Arc::new(written);
        let workers = (0..workers)
            .map(|_| {
                let receiver = receiver.clone();
                let shared = shared.clone();
                let written = written.clone();
                std::thread::spawn(move || loop {
                    let task = match receiver.lock().unwrap_or_else(|e| e.into_inner()).recv() {
                        Ok(task) => task,
                        Err(_) => return,
                    };
                    if shared
                        .error
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .is_some()
                    {
                        continue;
                    }
                    match run(&task, &shared) {
                        Ok(()) => written(&task.path),
                        Err(e) => {
                            let mut first = shared.error.lock().unwrap_or_else(|e| e.into_inner());
                            first.get_or_insert(e);
                        }
                    }
                })
            })
            .collect();
        WriteQueue {
            sender: Some(sender),
            workers,
            shared,
        }
    }

    /// Hands `frame` over to be written at `path`, waiting while every
    /// worker is busy; the first failure of an earlier frame instead.
    pub fn push(&self, frame: &Arc<Encoded>, path: PathBuf) -> Result<(), Error> {
        self.check()?;
        let task = Task {
            frame: frame.clone(),
            path,
        };
        match self.sender.as_ref().map(|s| s.send(task)) {
            Some(Ok(())) => Ok(()),
            _ => Err(self
                .take_error()
                .unwrap_or_else(|| Error::InvalidOption("the image writers stopped".into()))),
        }
    }

    /// The first failure so far, if any.
    pub fn check(&self) -> Result<(), Error> {
        match self.take_error() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    fn take_error(&self) -> Option<Error> {
        self.shared
            .error
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
    }

    /// Waits for every frame handed over; the workers' encode and write
    /// times, or the first failure.
    pub fn finish(mut self) -> Result<Timings, Error> {
        self.join();
        self.check()?;
        Ok(std::mem::take(
            &mut *self
                .shared
                .timings
                .lock()
                .unwrap_or_else(|e| e.into_inner()),
        ))
    }
}

impl Drop for WriteQueue {
    /// Dropped without `finish` (an error elsewhere): the frames handed
    /// over are still written whole.
    fn drop(&mut self) {
        self.join();
    }
}

impl WriteQueue {
    /// Closes the queue and waits for the workers to write what it holds.
    fn join(&mut self) {
        self.sender = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

fn run(task: &Task, shared: &Shared) -> Result<(), Error> {
    let f = &task.frame;
    let start = Instant::now();
    let mut encoded_here = false;
    let bytes = f.bytes.get_or_init(|| {
        encoded_here = true;
        f.image.encode(f.kind, &f.options)
    });
    let encode_time = start.elapsed();
    let bytes = bytes.as_ref().map_err(|e| Error::WriteImage {
        path: task.path.clone(),
        error: std::io::Error::other(e.clone()),
    })?;
    let start = Instant::now();
    write_bytes(&task.path, bytes)?;
    let mut t = shared.timings.lock().unwrap_or_else(|e| e.into_inner());
    if encoded_here {
        t.add("encode", encode_time);
    }
    t.add("write", start.elapsed());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::framebuffer::Framebuffer;

    fn frame(v: f32) -> Image {
        Image::Float(Framebuffer {
            width: 4,
            height: 3,
            pixels: vec![[v, 0.5, 0.25]; 12],
        })
    }

    /// Frames land as files, each written once and whole; a frame shared
    /// by several files is encoded once.
    #[test]
    fn writes_every_frame_and_encodes_a_shared_one_once() {
        let dir = tempfile::tempdir().expect("temp dir");
        let count = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let c = count.clone();
        let q = WriteQueue::new(2, move |_| {
            c.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        });
        let shared = Encoded::new(frame(0.5), ImageFile::Png, EncodeOptions::default());
        for i in 0..5 {
            q.push(&shared, dir.path().join(format!("{i}.png")))
                .expect("queued");
        }
        let own = Encoded::new(frame(0.1), ImageFile::Png, EncodeOptions::default());
        q.push(&own, dir.path().join("own.png")).expect("queued");
        let timings = q.finish().expect("written");
        assert_eq!(count.load(std::sync::atomic::Ordering::Relaxed), 6);
        let first = std::fs::read(dir.path().join("0.png")).expect("written");
        for i in 1..5 {
            assert_eq!(
                std::fs::read(dir.path().join(format!("{i}.png"))).expect("written"),
                first
            );
        }
        assert_ne!(
            std::fs::read(dir.path().join("own.png")).expect("written"),
            first
        );
        assert!(timings.phase("encode").is_some() && timings.phase("write").is_some());
    }

    /// A write that fails is reported by the next push or by finish, and
    /// the frames after it are not written.
    #[test]
    fn a_failed_write_is_reported() {
        let dir = tempfile::tempdir().expect("temp dir");
        let q = WriteQueue::new(1, |_| {});
        let f = Encoded::new(frame(0.5), ImageFile::Png, EncodeOptions::default());
        q.push(&f, dir.path().join("missing/0.png"))
            .expect("queued");
        let mut failed = false;
        for i in 1..50 {
            if q.push(&f, dir.path().join(format!("{i}.png"))).is_err() {
                failed = true;
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        let finished = q.finish();
        assert!(failed || finished.is_err(), "the failure went unreported");
    }
}
