//! Long renders: the render loop that works in short sample passes, so that
//! progress can be shown, a time limit kept, and the work saved to a
//! checkpoint periodically and when the process is asked to stop.
//!
//! A [`Session`] renders the samples of its *target range* that a [`Film`]
//! is missing, in passes of whole samples per pixel (every pixel gets
//! samples `a..b`, through [`Renderer::render_samples`]). The target range
//! is `0..spp` for a whole render, or one shard's sample range
//! ([`SessionOptions::samples`], see [`crate::run::shard`]): a shard is rendered
//! by the same loop, with the same progress, time limit, checkpoints and
//! partial outputs, and its checkpoints are accumulation files like its
//! partial file (same format, same header, see [`crate::film::AccMeta`]). Passes are sized from the measured speed to
//! last about [`SessionOptions::pass_target`] (0.5 s by default; never less
//! than one sample per pixel), so that between two passes — where signals,
//! the time limit, checkpoints and partial images are looked at — there is
//! never long to wait. Passes are also cut short to end when the next
//! checkpoint or partial image is due, so those are written on time.
//!
//! Because the film sums samples exactly (see [`crate::film`]), how the
//! samples were split into passes, runs and resumes does not change a single
//! bit of the image.

use crate::error::{Error, Result};
use crate::film::{AccMeta, Film};
use crate::integrator::Counters;
use crate::output::view::ViewTransform;
use crate::output::write_output_viewed;
use crate::render::{RenderSettings, Renderer};
use std::ops::Range;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// The default length of one pass.
pub const DEFAULT_PASS_TARGET: Duration = Duration::from_millis(500);

/// A pass expected to run longer than this many seconds can be stopped by
/// a signal part-way through (see [`Renderer::render_samples_or_stop`]).
pub const LONG_PASS_SECONDS: f64 = 1.0;

/// A first pass over more pixels than this can be stopped part-way (its
/// speed is not known yet; one sample of each pixel may take long).
pub const LONG_PASS_PIXELS: usize = 1 << 22;

/// The default interval between checkpoints.
pub const DEFAULT_CHECKPOINT_EVERY: Duration = Duration::from_secs(60);

/// The exit status of a process whose render was stopped by a fatal signal
/// that arrived while it was already stopping for an earlier one (a second
/// Ctrl-C): it exits at once, without saving.
pub const EXIT_ABORTED: i32 = 1;

/// How a session renders beyond "all the samples, as fast as possible".
#[derive(Clone, Debug)]
pub struct SessionOptions {
    /// The sample indices to render, within `0..spp`: a shard's range
    /// (`--samples A..B`, `--shard I/N`); `None` for all of `0..spp`.
    pub samples: Option<Range<u32>>,
    /// Stop, once the next pass would not fit, this long after the session
    /// started. At least one pass is always rendered.
    pub time_limit: Option<Duration>,
    /// Save the film to this accumulation file every
    /// [`checkpoint_every`](Self::checkpoint_every) and when stopping.
    pub checkpoint: Option<PathBuf>,
    /// The interval between checkpoints.
    pub checkpoint_every: Duration,
    /// Write the film so far to this file every
    /// [`partial_every`](Self::partial_every) (`None`: never): an image, or
    /// an accumulation file for `.wtacc` (as [`write_output_viewed`] does).
    pub partial_image: Option<PathBuf>,
    /// The interval between partial images.
    pub partial_every: Duration,
    /// The length a pass should have.
    pub pass_target: Duration,
    /// The exposure and view transform of a PNG partial image.
    pub view: ViewTransform,
}

impl Default for SessionOptions {
    fn default() -> Self {
        Self {
            samples: None,
            time_limit: None,
            checkpoint: None,
            checkpoint_every: DEFAULT_CHECKPOINT_EVERY,
            partial_image: None,
            partial_every: Duration::from_secs(10),
            pass_target: DEFAULT_PASS_TARGET,
            view: ViewTransform::default(),
        }
    }
}

/// Why a session stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// Every sample was rendered.
    Complete,
    /// The next pass would not have fitted in the time limit.
    TimeLimit,
    /// The process got this signal (SIGINT or SIGTERM).
    Signal(i32),
}

impl Stop {
    /// How stats and messages name the reason.
    pub fn name(self) -> &'static str {
        match self {
            Stop::Complete => "complete",
            Stop::TimeLimit => "time-limit",
            Stop::Signal(s) => signal_name(s),
        }
    }

    /// The process exit status for this stop: 0 when the image was
    /// rendered (completely or up to the time limit), 128 + the signal
    /// number when stopped by a signal (130 for SIGINT, 143 for SIGTERM),
    /// the shells' convention for "ended by that signal".
    pub fn exit_status(self) -> u8 {
        match self {
            Stop::Complete | Stop::TimeLimit => 0,
            Stop::Signal(s) => (128 + s).clamp(0, 255) as u8,
        }
    }
}

/// The name of a signal number, for messages.
pub fn signal_name(signal: i32) -> &'static str {
    match signal {
        signal_hook::consts::SIGINT => "SIGINT",
        signal_hook::consts::SIGTERM => "SIGTERM",
        _ => "signal",
    }
}

/// A request to stop, set by SIGINT or SIGTERM (see [`Interrupt::install`])
/// or by [`Interrupt::request`], and looked at between passes.
#[derive(Clone, Debug, Default)]
pub struct Interrupt {
    signal: Arc<AtomicUsize>,
    armed: Arc<AtomicBool>,
}

impl Interrupt {
    /// Catch SIGINT and SIGTERM from now on: the first one asks the render
    /// to stop after its current pass (and save a checkpoint); a second one
    /// ends the process at once with status [`EXIT_ABORTED`], saving
    /// nothing more (the last checkpoint written stays as it was).
    pub fn install() -> Result<Self> {
        let interrupt = Self::default();
        for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            let registered = (|| {
                // Order matters: the shutdown looks at `armed` before the
                // handlers below set it, so only a second signal ends.
                signal_hook::flag::register_conditional_shutdown(
                    sig,
                    EXIT_ABORTED,
                    Arc::clone(&interrupt.armed),
                )?;
                signal_hook::flag::register(sig, Arc::clone(&interrupt.armed))?;
                signal_hook::flag::register_usize(sig, Arc::clone(&interrupt.signal), sig as usize)
            })();
            registered.map_err(|e| {
                Error::Settings(format!(
                    "cannot catch {}: {e}; checkpoints on signals are unavailable",
                    signal_name(sig)
                ))
            })?;
        }
        Ok(interrupt)
    }

    /// Ask the render to stop as if `signal` had arrived.
    pub fn request(&self, signal: i32) {
        self.armed.store(true, Ordering::SeqCst);
        self.signal.store(signal as usize, Ordering::SeqCst);
    }

    /// The signal that asked the render to stop, if any did.
    pub fn requested(&self) -> Option<i32> {
        match self.signal.load(Ordering::SeqCst) {
            0 => None,
            s => Some(s as i32),
        }
    }
}

/// What a session did.
#[derive(Clone, Debug)]
pub struct SessionReport {
    /// The film: what it held at the start plus this session's samples.
    pub film: Film,
    /// Work done by this session (not by the runs it resumed).
    pub counters: Counters,
    /// Why it stopped.
    pub stop: Stop,
    /// Samples per pixel the film held when the session started.
    pub start_spp: u64,
    /// Passes rendered.
    pub passes: u32,
    /// Seconds spent in passes (rendering only).
    pub render_seconds: f64,
    /// Seconds of the longest pass.
    pub longest_pass_seconds: f64,
    /// Wall-clock seconds from the session's start to its stop.
    pub elapsed_seconds: f64,
    /// Checkpoints saved during the session (not the final one).
    pub checkpoints_saved: u32,
    /// Seconds spent saving checkpoints.
    pub checkpoint_seconds: f64,
    /// Partial images written.
    pub partial_images: u32,
    /// Seconds spent writing partial images.
    pub partial_seconds: f64,
}

/// What a session tells its caller while it runs (a progress bar, say).
/// Every method does nothing by default.
pub trait Observer {
    /// The session starts: `total` samples per pixel to hold, `done` of
    /// them already held (a resumed film).
    fn start(&mut self, total: u64, done: u64) {
        let _ = (total, done);
    }
    /// A pass has ended.
    fn pass(&mut self, progress: &Progress) {
        let _ = progress;
    }
    /// A checkpoint or partial image could not be written; the session
    /// goes on and tries again at the next interval.
    fn warning(&mut self, message: &str) {
        let _ = message;
    }
    /// The session has stopped.
    fn finish(&mut self) {}
}

/// An [`Observer`] that ignores everything.
impl Observer for () {}

/// Where a session stands after a pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Samples per pixel held of the target range.
    pub done: u64,
    /// Samples per pixel of the target range.
    pub total: u64,
    /// The samples per pixel the session will end with: `total`, or fewer
    /// when the time limit comes first.
    pub expected: u64,
    /// Rays per second of rendering so far.
    pub rays_per_second: f64,
    /// Seconds left until the session ends (all samples, or the time
    /// limit), at the speed of the last pass.
    pub eta_seconds: f64,
    /// Whether the time limit, not the samples, ends the session.
    pub time_limited: bool,
}

impl Progress {
    fn new(
        report: &SessionReport,
        done: u64,
        total: u64,
        per_sample: Option<f64>,
        time_limit: Option<Duration>,
        start: Instant,
    ) -> Self {
        let rays_per_second = report.counters.rays as f64 / report.render_seconds.max(1e-9);
        let mut eta = per_sample.unwrap_or(0.0) * total.saturating_sub(done) as f64;
        let mut expected = total;
        let mut time_limited = false;
        if let Some(limit) = time_limit {
            let left = limit.saturating_sub(start.elapsed()).as_secs_f64();
            if left < eta {
                eta = left;
                time_limited = true;
                let fit = (left / per_sample.unwrap_or(f64::INFINITY)).floor() as u64;
                expected = (done + fit).min(total);
            }
        }
        Self {
            done,
            total,
            expected,
            rays_per_second,
            eta_seconds: eta.max(0.0),
            time_limited,
        }
    }
}

/// The render loop of one run: renders the samples of the target range
/// ([`Session::target`]) that a film is missing, in passes.
pub struct Session<'a> {
    renderer: &'a Renderer,
    meta: AccMeta,
    options: SessionOptions,
    /// Samples per pixel of the film at the last checkpoint.
    saved_spp: Option<u64>,
}

impl<'a> Session<'a> {
    /// A session for `renderer`. `meta` is the header of the accumulation
    /// files it writes (checkpoints, and `.wtacc` partial outputs): the
    /// settings hash ([`crate::render::RenderSettings::image_hash`]), the
    /// render's `spp` and the shard, as in the render's partial file.
    pub fn new(renderer: &'a Renderer, meta: AccMeta, options: SessionOptions) -> Self {
        Self {
            renderer,
            meta,
            options,
            saved_spp: None,
        }
    }

    /// The sample range this session renders:
    /// [`SessionOptions::samples`], or `0..spp`.
    pub fn target(&self) -> Range<u32> {
        target_range(&self.options, self.renderer.settings())
    }

    /// Render what `film` is missing of the [target range](Self::target),
    /// until done, out of time, or interrupted. `film` must hold no sample
    /// outside the target range ([`check_resumable`]). Checkpoints and partial images are written
    /// as they fall due; one that cannot be written is reported as a
    /// warning and tried again at the next interval. The final
    /// checkpoint and image are left to the caller
    /// ([`save_checkpoint`](Self::save_checkpoint)).
    pub fn run(
        &mut self,
        mut film: Film,
        interrupt: &Interrupt,
        observer: &mut dyn Observer,
    ) -> Result<SessionReport> {
        let target = self.target();
        check_resumable(&film, self.renderer.settings(), &target).map_err(Error::Settings)?;
        let o = self.options.clone();
        let start = Instant::now();
        let start_spp = film.samples_per_pixel();
        if self.saved_spp.is_none() && o.checkpoint.is_some() {
            // A resumed film is already saved; a new one has nothing worth saving.
            self.saved_spp = Some(start_spp);
        }
        let mut report = SessionReport {
            film: Film::new(0, 0),
            counters: Counters::default(),
            stop: Stop::Complete,
            start_spp,
            passes: 0,
            render_seconds: 0.0,
            longest_pass_seconds: 0.0,
            elapsed_seconds: 0.0,
            checkpoints_saved: 0,
            checkpoint_seconds: 0.0,
            partial_images: 0,
            partial_seconds: 0.0,
        };
        // Progress counts the target range's samples (a shard's, say).
        let total = (target.end - target.start) as u64;
        observer.start(total, start_spp);
        let mut next_checkpoint = o.checkpoint.as_ref().map(|_| o.checkpoint_every);
        let mut next_partial = o.partial_image.as_ref().map(|_| o.partial_every);
        // Seconds per sample per pixel, measured by the last pass.
        let mut per_sample: Option<f64> = None;

        report.stop = loop {
            // Done is done: a signal that arrives as the last pass ends
            // does not stop a render that has every sample.
            let Some(gap) = first_gap(&film.ranges, &target) else {
                break Stop::Complete;
            };
            if let Some(sig) = interrupt.requested() {
                break Stop::Signal(sig);
            }
            let now = start.elapsed();
            let plan = PassPlan {
                now: now.as_secs_f64(),
                per_sample,
                target: o.pass_target.as_secs_f64(),
                remaining: gap.end - gap.start,
                due: [next_checkpoint, next_partial].map(|d| d.map(|d| d.as_secs_f64())),
                limit: o.time_limit.map(|d| d.as_secs_f64()),
            };
            let Some(n) = plan.samples() else {
                break Stop::TimeLimit;
            };

            let pass_start = Instant::now();
            let samples = gap.start..gap.start + n;
            // A pass expected to take long (one at the 1-sample floor of a
            // huge image, or a first pass over more than LONG_PASS_PIXELS
            // before its speed is known) can be stopped by a signal between
            // tiles; the film then keeps only the passes that finished.
            // Other passes (the usual ~0.5 s) run in place, without the
            // film-sized accumulator that stopping part-way needs.
            let long = match per_sample {
                Some(p) => p * n as f64 > LONG_PASS_SECONDS,
                None => film.sums.len() > LONG_PASS_PIXELS,
            };
            let c = if long {
                let stop = || interrupt.requested().is_some();
                match self
                    .renderer
                    .render_samples_or_stop(samples, &mut film, &stop)
                {
                    Some(c) => c,
                    None => {
                        break Stop::Signal(interrupt.requested().expect("stopped by a signal"));
                    }
                }
            } else {
                self.renderer.render_samples(samples, &mut film)
            };
            let dt = pass_start.elapsed().as_secs_f64();
            report.counters += c;
            report.passes += 1;
            report.render_seconds += dt;
            report.longest_pass_seconds = report.longest_pass_seconds.max(dt);
            per_sample = Some(dt / n as f64);

            let done = film.samples_per_pixel();
            let now = start.elapsed();
            if let Some(due) = next_checkpoint
                && now >= due
            {
                let t = Instant::now();
                match self.save_checkpoint(&film) {
                    Ok(saved) => report.checkpoints_saved += saved as u32,
                    Err(e) => {
                        observer.warning(&format!("checkpoint not saved (will try again): {e}"))
                    }
                }
                report.checkpoint_seconds += t.elapsed().as_secs_f64();
                next_checkpoint = Some(start.elapsed().saturating_add(o.checkpoint_every));
            }
            if let (Some(due), Some(path)) = (next_partial, &o.partial_image)
                && now >= due
            {
                let t = Instant::now();
                match write_output_viewed(path, &film, &self.meta, o.view) {
                    Ok(()) => report.partial_images += 1,
                    Err(e) => observer
                        .warning(&format!("partial image not written (will try again): {e}")),
                }
                report.partial_seconds += t.elapsed().as_secs_f64();
                next_partial = Some(start.elapsed().saturating_add(o.partial_every));
            }
            observer.pass(&Progress::new(
                &report,
                done,
                total,
                per_sample,
                o.time_limit,
                start,
            ));
        };
        observer.finish();
        report.elapsed_seconds = start.elapsed().as_secs_f64();
        report.film = film;
        Ok(report)
    }

    /// Save `film` to the checkpoint file (atomically, with the session's
    /// [`AccMeta`]: the same format and header as the render's partial
    /// file), unless there is no checkpoint file or it already holds
    /// exactly these samples. Returns whether a file was written.
    pub fn save_checkpoint(&mut self, film: &Film) -> Result<bool> {
        let Some(path) = &self.options.checkpoint else {
            return Ok(false);
        };
        let spp = film.samples_per_pixel();
        if self.saved_spp == Some(spp) && path.exists() {
            return Ok(false);
        }
        film.save_with_meta(path, &self.meta)?;
        self.saved_spp = Some(spp);
        Ok(true)
    }
}

/// The sample range `options` asks for: [`SessionOptions::samples`], or
/// `0..settings.spp`.
pub fn target_range(options: &SessionOptions, settings: &RenderSettings) -> Range<u32> {
    options.samples.clone().unwrap_or(0..settings.spp)
}

/// Whether `film` can be continued to the sample range `target` of a render
/// with `settings`: it has the settings' size and AOVs and holds no sample
/// outside `target` (for a whole render, `0..spp`: no sample at or beyond
/// `spp`). A checkpoint of a shard therefore resumes with that shard's
/// range, or with any range that contains it. The error says what is wrong.
pub fn check_resumable(
    film: &Film,
    settings: &RenderSettings,
    target: &Range<u32>,
) -> std::result::Result<(), String> {
    if (film.width, film.height) != (settings.width, settings.height) {
        return Err(format!(
            "made for a {}x{} image, not {}x{}",
            film.width, film.height, settings.width, settings.height
        ));
    }
    if film.aovs() != settings.aovs {
        return Err(format!(
            "holds the AOVs {}, but this render asks for {} (--aov, and albedo,normal for --denoise); \
             a checkpoint's AOVs cannot change: resume it {}",
            film.aovs(),
            settings.aovs,
            if film.aovs().is_empty() {
                "without --aov or --denoise".to_string()
            } else {
                format!("with --aov {}", film.aovs())
            }
        ));
    }
    let (Some(first), Some(last)) = (film.ranges.first(), film.ranges.last()) else {
        return Ok(());
    };
    if first.start >= target.start && last.end <= target.end {
        return Ok(());
    }
    if *target == (0..settings.spp) {
        return Err(format!(
            "holds samples up to {} ({} spp), more than --spp {}; ask for --spp {} or more",
            last.end,
            film.samples_per_pixel(),
            settings.spp,
            last.end
        ));
    }
    let held: Vec<String> = film
        .ranges
        .iter()
        .map(|r| format!("{}..{}", r.start, r.end))
        .collect();
    Err(format!(
        "holds samples {}, outside samples {}..{} of {} that this render is to do; \
         resume it with the --spp and --shard (or --samples) it was made with",
        held.join(", "),
        target.start,
        target.end,
        settings.spp
    ))
}

/// The first run of samples in `target` that `held` (sorted, disjoint
/// ranges) does not hold.
pub fn first_gap(held: &[Range<u32>], target: &Range<u32>) -> Option<Range<u32>> {
    let mut start = target.start;
    for r in held {
        if r.start > start {
            break;
        }
        start = start.max(r.end);
    }
    let end = held
        .iter()
        .map(|r| r.start)
        .find(|&s| s > start)
        .unwrap_or(target.end)
        .min(target.end);
    (start < end).then_some(start..end)
}

/// What decides the size of the next pass. Times are seconds since the
/// session started.
#[derive(Clone, Copy, Debug)]
struct PassPlan {
    now: f64,
    /// Seconds one sample per pixel took in the last pass.
    per_sample: Option<f64>,
    target: f64,
    /// Samples left in the gap being filled.
    remaining: u32,
    /// When the next checkpoint and partial image are due.
    due: [Option<f64>; 2],
    limit: Option<f64>,
}

impl PassPlan {
    /// Samples per pixel for the next pass, or `None` when it would not fit
    /// in the time limit. The first pass (speed unknown) is 1 sample.
    fn samples(&self) -> Option<u32> {
        let Some(t) = self.per_sample else {
            return Some(1);
        };
        let t = t.max(1e-9);
        let mut n = (self.target / t).floor().max(1.0);
        for due in self.due.into_iter().flatten() {
            n = n.min(((due - self.now) / t).floor().max(1.0));
        }
        if let Some(limit) = self.limit {
            let fit = ((limit - self.now) / t).floor();
            if fit < 1.0 {
                return None;
            }
            n = n.min(fit);
        }
        Some((n.min(self.remaining as f64) as u32).max(1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(per_sample: Option<f64>) -> PassPlan {
        PassPlan {
            now: 10.0,
            per_sample,
            target: 0.5,
            remaining: 1000,
            due: [None, None],
            limit: None,
        }
    }

    #[test]
    fn first_pass_is_one_sample() {
        assert_eq!(plan(None).samples(), Some(1));
        let p = PassPlan {
            limit: Some(0.0),
            ..plan(None)
        };
        assert_eq!(p.samples(), Some(1), "at least one pass is rendered");
    }

    // Times below are binary fractions, so the arithmetic is exact.
    const T: f64 = 1.0 / 64.0;

    #[test]
    fn passes_last_about_the_target() {
        assert_eq!(plan(Some(T)).samples(), Some(32));
        assert_eq!(plan(Some(2.0)).samples(), Some(1), "never below 1 spp");
        assert_eq!(plan(Some(1e-6)).samples(), Some(1000), "never past the gap");
    }

    #[test]
    fn passes_end_when_a_checkpoint_is_due() {
        let p = PassPlan {
            due: [Some(10.25), Some(11.0)],
            ..plan(Some(T))
        };
        assert_eq!(p.samples(), Some(16));
        let overdue = PassPlan {
            due: [Some(9.0), None],
            ..plan(Some(T))
        };
        assert_eq!(overdue.samples(), Some(1));
    }

    #[test]
    fn time_limit_stops_when_the_next_pass_would_not_fit() {
        let p = |limit| PassPlan {
            limit: Some(limit),
            ..plan(Some(T))
        };
        assert_eq!(p(20.0).samples(), Some(32));
        assert_eq!(p(10.25).samples(), Some(16));
        assert_eq!(p(10.0 + 1.5 * T).samples(), Some(1));
        assert_eq!(p(10.0 + 0.5 * T).samples(), None);
        assert_eq!(p(9.0).samples(), None);
    }

    #[test]
    #[allow(clippy::single_range_in_vec_init)] // lists of sample ranges
    fn gaps() {
        assert_eq!(first_gap(&[], &(0..8)), Some(0..8));
        assert_eq!(first_gap(&[0..8], &(0..8)), None);
        assert_eq!(first_gap(&[0..3], &(0..8)), Some(3..8));
        assert_eq!(first_gap(&[2..4], &(0..8)), Some(0..2));
        assert_eq!(first_gap(&[0..2, 5..6], &(0..8)), Some(2..5));
        assert_eq!(first_gap(&[0..2, 5..8], &(0..8)), Some(2..5));
        assert_eq!(first_gap(&[0..8], &(0..4)), None);
    }

    #[test]
    #[allow(clippy::single_range_in_vec_init)] // lists of sample ranges
    fn gaps_in_a_shard_range() {
        assert_eq!(first_gap(&[], &(16..32)), Some(16..32));
        assert_eq!(first_gap(&[16..20], &(16..32)), Some(20..32));
        assert_eq!(first_gap(&[16..20, 24..28], &(16..32)), Some(20..24));
        assert_eq!(first_gap(&[16..32], &(16..32)), None);
        assert_eq!(first_gap(&[20..24], &(16..32)), Some(16..20));
        // Samples held outside the target do not count (a whole film
        // continued as a shard would be refused by check_resumable first).
        assert_eq!(first_gap(&[0..16], &(16..32)), Some(16..32));
        assert_eq!(first_gap(&[0..20, 30..40], &(16..32)), Some(20..30));
    }

    #[test]
    #[allow(clippy::single_range_in_vec_init)] // lists of sample ranges
    fn resumable_only_within_the_target() {
        let scene = crate::scene::Scene::cornell();
        let mut settings = RenderSettings::for_scene(&scene);
        (settings.width, settings.height, settings.spp) = (2, 2, 64);
        let film = |ranges: &[Range<u32>]| {
            let mut f = Film::new(2, 2);
            for r in ranges {
                f.add_range(r.clone());
            }
            f
        };
        let ok = |ranges: &[Range<u32>], target: Range<u32>| {
            check_resumable(&film(ranges), &settings, &target)
        };
        assert!(ok(&[], 16..32).is_ok());
        assert!(ok(&[16..20], 16..32).is_ok());
        assert!(ok(&[16..32], 16..32).is_ok());
        assert!(
            ok(&[16..20], 0..64).is_ok(),
            "a shard's film, finished whole"
        );
        let e = ok(&[16..20], 32..48).unwrap_err();
        assert!(
            e.contains("samples 16..20, outside samples 32..48 of 64"),
            "{e}"
        );
        assert!(ok(&[8..20], 16..32).is_err());
        let e = ok(&[0..80], 0..64).unwrap_err();
        assert!(e.contains("more than --spp 64"), "{e}");
        assert!(check_resumable(&Film::new(3, 2), &settings, &(0..64)).is_err());
        let depth = crate::scene::AovSet::of(&[crate::scene::Aov::Depth]);
        let e = check_resumable(&Film::with_aovs(2, 2, depth), &settings, &(0..64)).unwrap_err();
        assert!(
            e.contains("holds the AOVs depth, but this render asks for none"),
            "{e}"
        );
        settings.aovs = depth;
        assert!(check_resumable(&Film::with_aovs(2, 2, depth), &settings, &(0..64)).is_ok());
        let e = check_resumable(&Film::new(2, 2), &settings, &(0..64)).unwrap_err();
        assert!(e.contains("resume it without --aov"), "{e}");
    }

    #[test]
    fn exit_statuses() {
        assert_eq!(Stop::Complete.exit_status(), 0);
        assert_eq!(Stop::TimeLimit.exit_status(), 0);
        assert_eq!(Stop::Signal(2).exit_status(), 130);
        assert_eq!(Stop::Signal(15).exit_status(), 143);
    }
}
