//! `wavetrace.views(job)`: a views job's views, rendered in memory on a
//! thread of their own and handed to Python one at a time as arrays — the
//! bits `wavetrace views` writes, without the files.
//!
//! The rendering thread runs [`wavetrace::run::views::stream`] and sends
//! each view through a channel of one slot, so it renders at most one
//! view ahead of the consumer. `__next__` waits with the GIL released,
//! checking for signals (Ctrl-C: `KeyboardInterrupt`, and the job stops);
//! dropping the iterator stops the job.

use super::{Buffer, Camera, buffers_of, error, settings_error};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;
use wavetrace::render::Engine;
use wavetrace::run::views::{ViewsOptions, ViewsReport, stream};
use wavetrace::scene::Aov;
use wavetrace::scene::camera::Camera as CoreCamera;
use wavetrace::scene::views_job::ViewsJob;

/// One view, as the rendering thread sends it.
struct Item {
    asset: String,
    file: PathBuf,
    view: u32,
    camera: CoreCamera,
    buffers: Vec<(&'static str, Buffer)>,
    objects: Vec<(u32, String)>,
}

enum Message {
    View(Box<Item>),
    Done(wavetrace::Result<ViewsReport>),
}

/// The views of a job, in order (asset by asset, view by view).
#[pyclass(frozen, module = "wavetrace._wavetrace")]
pub struct Views {
    rx: Mutex<Option<mpsc::Receiver<Message>>>,
    stop: Arc<AtomicBool>,
    thread: Mutex<Option<std::thread::JoinHandle<()>>>,
    /// `(asset file, error)` of the assets that could not be rendered.
    failed: Mutex<Vec<(String, String)>>,
    /// Views in this run's share.
    total: u64,
}

impl Views {
    /// Stop the job and wait for its thread (which then ends at its next
    /// tile or view).
    fn shut(&self) {
        self.stop.store(true, Ordering::Relaxed);
        // Dropping the receiver ends a send the thread is blocked in.
        self.rx.lock().expect("not poisoned").take();
        if let Some(t) = self.thread.lock().expect("not poisoned").take() {
            let _ = t.join();
        }
    }
}

impl Drop for Views {
    fn drop(&mut self) {
        self.shut();
    }
}

/// Start a views job in memory. See `wavetrace.views`.
#[pyfunction]
#[pyo3(signature = (job, threads = None, shard = None, engine = None))]
pub fn views(
    py: Python<'_>,
    job: PathBuf,
    threads: Option<usize>,
    shard: Option<(u32, u32)>,
    engine: Option<&str>,
) -> PyResult<Views> {
    let job = py
        .detach(|| ViewsJob::load(&job))
        .map_err(|e| error(e.into()))?;
    let threads =
        threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 || threads > wavetrace::render::MAX_THREADS {
        return Err(settings_error(format!(
            "threads must be 1 to {}: got {threads}",
            wavetrace::render::MAX_THREADS
        )));
    }
    if let Some((i, n)) = shard
        && (n == 0 || i >= n)
    {
        return Err(settings_error(format!(
            "shard (index, count) needs 0 <= index < count: got ({i}, {n})"
        )));
    }
    let engine = match engine {
        None => Engine::Wavefront,
        Some(n) => Engine::from_name(n).map_err(error)?,
    };
    let options = ViewsOptions {
        out_dir: PathBuf::new(),
        shard,
        threads,
        engine,
        batch_size: None,
        checkpoint_every: wavetrace::run::views::DEFAULT_CHECKPOINT_EVERY,
        pass_samples: None,
    };
    let pairs = job.assets.len() as u64 * u64::from(job.view_count());
    let share = wavetrace::run::views::shard_pairs(pairs, shard);
    let (tx, rx) = mpsc::sync_channel(1);
    let stop = Arc::new(AtomicBool::new(false));
    let stopped = stop.clone();
    let thread = std::thread::spawn(move || {
        let asked = job.outputs.aovs;
        let (w, h) = (job.render.width as usize, job.render.height as usize);
        let halt = || stopped.load(Ordering::Relaxed);
        let mut each = |v: wavetrace::run::views::StreamedView| {
            // The AOVs asked for, and the alpha wherever the files have it
            // (a transparent background adds it).
            let aovs = (v.aovs.into_iter())
                .filter(|(aov, _)| asked.contains(*aov) || *aov == Aov::Alpha)
                .collect();
            let item = Item {
                asset: v.asset.to_string(),
                file: v.file.to_path_buf(),
                view: v.view,
                camera: v.camera.clone(),
                buffers: buffers_of((w, h), v.rgb.to_vec(), aovs),
                objects: v.objects.to_vec(),
            };
            Ok(tx.send(Message::View(Box::new(item))).is_ok() && !halt())
        };
        let result = stream(&job, &options, &halt, &mut |_| {}, &mut each);
        let _ = tx.send(Message::Done(result));
    });
    Ok(Views {
        rx: Mutex::new(Some(rx)),
        stop,
        thread: Mutex::new(Some(thread)),
        failed: Mutex::new(Vec::new()),
        total: share.end - share.start,
    })
}

type Next = (
    String,
    PathBuf,
    u32,
    Vec<(&'static str, Buffer)>,
    Camera,
    Vec<(u32, String)>,
);

#[pymethods]
impl Views {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next view as `(asset, file, view, {name: Buffer}, camera,
    /// objects)`; `None` (StopIteration) at the end.
    fn __next__(&self, py: Python<'_>) -> PyResult<Option<Next>> {
        loop {
            let got = py.detach(|| {
                let rx = self.rx.lock().expect("not poisoned");
                match rx.as_ref() {
                    Some(rx) => rx.recv_timeout(Duration::from_millis(50)),
                    None => Err(mpsc::RecvTimeoutError::Disconnected),
                }
            });
            match got {
                Ok(Message::View(item)) => {
                    let i = *item;
                    return Ok(Some((
                        i.asset,
                        i.file,
                        i.view,
                        i.buffers,
                        Camera::from_core(&i.camera),
                        i.objects,
                    )));
                }
                Ok(Message::Done(result)) => {
                    self.shut();
                    let report = result.map_err(error)?;
                    let mut failed = self.failed.lock().expect("not poisoned");
                    for a in report.failed() {
                        failed.push((a.file.clone(), a.error.clone().unwrap_or_default()));
                    }
                    return Ok(None);
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => return Ok(None),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals() {
                        self.shut();
                        return Err(e);
                    }
                }
            }
        }
    }

    /// How many views this run renders (its shard's share).
    #[getter]
    fn total(&self) -> u64 {
        self.total
    }

    /// `(asset file, error)` for every asset that could not be rendered
    /// (known once the iteration has ended).
    #[getter]
    fn failed(&self) -> Vec<(String, String)> {
        self.failed.lock().expect("not poisoned").clone()
    }

    /// Stop the job now (the iteration then ends).
    fn close(&self, py: Python<'_>) {
        py.detach(|| self.shut());
    }
}
