//! `wavetrace views`: many views of many assets, resumable and sharded.
//!
//! A job ([`ViewsJob`]) names assets and cameras; its work is the
//! `(asset, view)` pairs, numbered asset by asset. A shard `I/N` renders
//! the pairs `⌊I·P/N⌋ .. ⌊(I+1)·P/N⌋` of the `P` pairs, so shards never
//! overlap and together cover the job. Each asset is loaded, and its
//! hierarchy, textures and tables built, once for all its views in the
//! shard; only the camera, the seed (and, when the job varies the
//! lighting, the lights) change between views.
//!
//! **Reproducible.** View `i` of an asset renders with the seed derived
//! from the job's [settings hash](ViewsJob::settings_hash), the asset
//! file's bytes and `i` ([`view_seed`]), and random cameras and lighting
//! choices from seeds derived the same way: a view's files are the same
//! bytes whatever the shard count, thread count, order or resumes.
//!
//! **Resumable.** A view's files are written whole (atomically), then its
//! record, `manifest/NNNN.json` beside them: the job and asset hashes and
//! every file with its hash. A view whose record matches the job, the
//! asset and its files on disk is skipped. The library prints nothing:
//! progress goes to the caller through [`ViewsEvent`]s.

use super::views_cameras::{
    Normalisation, Pose, normalisation, opencv_json, poses, transforms_json,
};
use crate::denoise::{Aux, Denoiser};
use crate::error::{Error, Result};
use crate::film::{AccMeta, Film};
use crate::fs::write_atomic;
use crate::integrator::StageSeconds;
use crate::output::ExrLayer;
use crate::output::view::ViewTransform;
use crate::render::{Engine, RenderSettings, Renderer};
use crate::scene::views_job::ViewsJob;
use crate::scene::{Aov, AovSet, Scene};
use glam::Vec3;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How to run a job: where, which part, and the tuning that never
/// changes a bit of the output.
#[derive(Clone, Debug)]
pub struct ViewsOptions {
    /// The output directory (one folder per asset inside).
    pub out_dir: PathBuf,
    /// The shard `(index, count)` to render; `None`: all of it.
    pub shard: Option<(u32, u32)>,
    /// Worker threads.
    pub threads: usize,
    /// The path tracer.
    pub engine: Engine,
    /// Paths per wavefront batch (`None`: the default).
    pub batch_size: Option<usize>,
    /// Save the view in progress to its checkpoint this often (and when
    /// stopped), so that a killed run goes on from there
    /// ([`DEFAULT_CHECKPOINT_EVERY`]).
    pub checkpoint_every: Duration,
    /// Samples per pixel per pass (`None`: passes of about half a second).
    pub pass_samples: Option<u32>,
}

/// How often a view in progress is saved by default.
pub const DEFAULT_CHECKPOINT_EVERY: Duration = Duration::from_secs(60);

/// How long a pass of a view's samples should take (between passes, its
/// checkpoint may be saved).
const PASS_SECONDS: f64 = 0.5;

/// What happened, as it happens (the command draws its progress from these).
#[derive(Debug)]
pub enum ViewsEvent<'a> {
    /// The work is planned: this many views in this run's share.
    Planned {
        /// Views in the shard.
        views: u64,
    },
    /// A view is done: rendered, or skipped (finished earlier).
    View {
        /// The asset's name.
        asset: &'a str,
        /// The view's index.
        view: u32,
        /// Whether it was finished already.
        skipped: bool,
        /// Seconds spent tracing paths.
        render_seconds: f64,
        /// Seconds spent on everything else of the view (AOVs, denoise,
        /// writing, hashing).
        write_seconds: f64,
    },
    /// An asset is done (or failed).
    Asset(&'a AssetReport),
}

/// What happened to one asset.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct AssetReport {
    /// Its folder's name.
    pub name: String,
    /// Its file.
    pub file: String,
    /// Seconds to read it (0 when every view was finished).
    pub load_seconds: f64,
    /// Seconds to build its hierarchy and tables.
    pub build_seconds: f64,
    /// Its triangles.
    pub triangles: usize,
    /// Views rendered by this run.
    pub views_rendered: u32,
    /// Views skipped, finished earlier.
    pub views_skipped: u32,
    /// Views of those rendered that went on from a checkpoint (a run
    /// stopped inside them).
    pub views_resumed: u32,
    /// Seconds tracing paths, all its views.
    pub render_seconds: f64,
    /// Seconds on the rest of its views (AOVs, denoise, writing, hashing).
    pub write_seconds: f64,
    /// Rays cast for its views by this run (closest-hit and shadow rays).
    pub rays: u64,
    /// Seconds in each wavefront stage, its views, summed over threads
    /// (zero for the reference engine).
    #[serde(serialize_with = "stage_map")]
    pub stages: StageSeconds,
    /// Of those, the seconds spent looking textures up (and making the
    /// material parameters they give): [`StageSeconds::textures`].
    pub texture_seconds: f64,
    /// Why it failed, if it did (its views are then not rendered).
    pub error: Option<String>,
}

/// [`StageSeconds`] as a map from each stage's name.
fn stage_map<S: serde::Serializer>(
    stages: &StageSeconds,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&stages.by_name(), s)
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct ViewsReport {
    /// The assets this run's share touched, in order.
    pub assets: Vec<AssetReport>,
    /// Views in this run's share.
    pub views: u64,
    /// Views rendered.
    pub rendered: u64,
    /// Views skipped (finished earlier).
    pub skipped: u64,
    /// Whether `stop` ended the run early (between views, or inside one,
    /// whose files are then not written).
    pub stopped: bool,
}

impl ViewsReport {
    /// The assets that failed.
    pub fn failed(&self) -> impl Iterator<Item = &AssetReport> {
        self.assets.iter().filter(|a| a.error.is_some())
    }
}

/// The decimal digits of view numbers in file names: those of the view
/// count (at least 1), so 1000 views are `0000..0999` and 10000 are
/// `00000..09999`; a name never wraps or grows within a job.
pub fn name_width(views: u32) -> usize {
    views.max(1).to_string().len()
}

/// The folder names of `assets`: each file's stem, with `-K` (its index
/// in the list) added where stems repeat.
pub fn asset_names(assets: &[PathBuf]) -> Vec<String> {
    let stem = |p: &PathBuf| {
        p.file_stem()
            .map_or("asset".into(), |s| s.to_string_lossy().into_owned())
    };
    let stems: Vec<String> = assets.iter().map(stem).collect();
    stems
        .iter()
        .enumerate()
        .map(|(i, s)| {
            if stems.iter().filter(|t| *t == s).count() > 1 {
                format!("{s}-{i}")
            } else {
                s.clone()
            }
        })
        .collect()
}

/// The pairs `(asset, view)` of shard `(index, count)` of `pairs`, as a
/// range of pair numbers (`asset · views + view`).
pub fn shard_pairs(pairs: u64, shard: Option<(u32, u32)>) -> std::ops::Range<u64> {
    match shard {
        None => 0..pairs,
        Some((i, n)) => {
            let at = |k: u32| (u128::from(pairs) * u128::from(k) / u128::from(n)) as u64;
            at(i)..at(i + 1)
        }
    }
}

/// A seed from the job's settings hash, the asset's hash, a view and a
/// purpose.
fn derive(job: u128, asset: u128, view: u32, purpose: &[u8]) -> u64 {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(&job.to_le_bytes());
    h.update(&asset.to_le_bytes());
    h.update(&view.to_le_bytes());
    h.update(purpose);
    h.digest()
}

/// The render seed of view `view` of the asset whose bytes hash to
/// `asset`, in the job whose settings hash to `job`.
pub fn view_seed(job: u128, asset: u128, view: u32) -> u64 {
    derive(job, asset, view, b"render")
}

/// The 128-bit hash of the asset file's bytes (what its views' seeds are
/// derived from).
fn asset_hash(path: &Path) -> Result<u128> {
    let bytes = std::fs::read(path)
        .map_err(|e| Error::Settings(format!("{}: cannot read the asset: {e}", path.display())))?;
    Ok(xxhash_rust::xxh3::xxh3_128(&bytes))
}

/// An asset as the views render it: its scene (its own light, or the
/// default sky where it has none) and bounds.
fn load_asset(path: &Path) -> Result<(Scene, Vec3, Vec3)> {
    let scene = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
    {
        Scene::load(path)?
    } else {
        let asset = crate::scene::mesh_source::load(path)
            .map_err(crate::scene::asset_scene::scene_error)?;
        let name = path
            .file_stem()
            .map_or("asset".into(), |s| s.to_string_lossy().into_owned());
        crate::scene::asset_scene::scene_from_asset(
            &asset,
            &name,
            &path.display().to_string(),
            None,
        )?
    };
    let (lo, hi) = scene.bounds();
    if scene.primitive_count() == 0 || !(lo.is_finite() && hi.is_finite()) {
        return Err(Error::Settings(format!(
            "{}: nothing to render",
            path.display()
        )));
    }
    Ok((scene, lo, hi))
}

/// Run `job`'s share (`options.shard`) into `options.out_dir`, skipping
/// finished views; `stop()` is asked between views and tiles. A broken
/// asset is recorded in its [`AssetReport`] and the run goes on; errors
/// are for what stops the whole job (an output that cannot be written,
/// the denoiser missing).
pub fn run(
    job: &ViewsJob,
    options: &ViewsOptions,
    stop: &(dyn Fn() -> bool + Sync),
    observe: &mut dyn FnMut(ViewsEvent),
) -> Result<ViewsReport> {
    std::fs::create_dir_all(&options.out_dir)
        .map_err(|e| crate::fs::FileError::new(&options.out_dir, e))?;
    run_into(job, options, &mut Sink::Files, stop, observe)
}

/// A view rendered by [`stream`], in memory: what `run` would write.
pub struct StreamedView<'a> {
    /// The asset's name (its output folder's in `run`).
    pub asset: &'a str,
    /// The asset's file.
    pub file: &'a Path,
    /// The view's index among the asset's views.
    pub view: u32,
    /// The view's camera in the job's world (`transforms.json`'s).
    pub camera: &'a Pose,
    /// How the asset's coordinates map to the job's world (depths in the
    /// job's world units are the film's times `scale`).
    pub normalisation: &'a Normalisation,
    /// The film as accumulated (sample counts, hits).
    pub film: &'a Film,
    /// The AOVs the job asks for, as `run` writes them: depths in the
    /// job's world units, normals in the axes the job asks for.
    pub aovs: Vec<(Aov, Vec<[f32; 3]>)>,
    /// The colour as `run` writes it (denoised when the job denoises).
    pub rgb: &'a [[f32; 3]],
    /// The asset's object-id legend, `(id, name)`.
    pub objects: &'a [(u32, String)],
}

/// Render `job`'s share (`options.shard`; `options.out_dir` is not used)
/// in memory, handing each view to `each` in order; nothing is written
/// and nothing is skipped. `each` returns false to end the job early (the
/// report then says `stopped`). Broken assets are reported as by [`run`].
/// A view's colour and AOVs are the bits `run` writes for it.
pub fn stream(
    job: &ViewsJob,
    options: &ViewsOptions,
    stop: &(dyn Fn() -> bool + Sync),
    observe: &mut dyn FnMut(ViewsEvent),
    each: &mut dyn FnMut(StreamedView) -> Result<bool>,
) -> Result<ViewsReport> {
    run_into(job, options, &mut Sink::Memory(each), stop, observe)
}

/// Where rendered views go.
enum Sink<'a> {
    /// Files in the output directory, with records (resumable).
    Files,
    /// A caller's function ([`stream`]).
    Memory(&'a mut dyn FnMut(StreamedView) -> Result<bool>),
}

fn run_into(
    job: &ViewsJob,
    options: &ViewsOptions,
    sink: &mut Sink,
    stop: &(dyn Fn() -> bool + Sync),
    observe: &mut dyn FnMut(ViewsEvent),
) -> Result<ViewsReport> {
    let views = job.view_count();
    let pairs = job.assets.len() as u64 * u64::from(views);
    let share = shard_pairs(pairs, options.shard);
    let mut report = ViewsReport {
        views: share.end - share.start,
        ..ViewsReport::default()
    };
    observe(ViewsEvent::Planned {
        views: report.views,
    });
    let mut denoiser = match job.render.denoise {
        true => Some(Denoiser::new()?),
        false => None,
    };
    let names = asset_names(&job.assets);
    let job_hash = job.settings_hash();
    let per_asset = u64::from(views.max(1));
    let first = (share.start / per_asset) as usize;
    let last = share.end.div_ceil(per_asset) as usize;
    let assets = job.assets.iter().zip(&names).enumerate();
    for (a, (path, name)) in assets.take(last).skip(first) {
        let lo = (a as u64 * per_asset).max(share.start) - a as u64 * per_asset;
        let hi = ((a as u64 + 1) * per_asset).min(share.end) - a as u64 * per_asset;
        let mut asset = AssetReport {
            name: name.clone(),
            file: path.display().to_string(),
            ..AssetReport::default()
        };
        let range = lo as u32..hi as u32;
        let work = AssetWork {
            job,
            name,
            options,
            job_hash,
            path,
            dir: options.out_dir.join(name),
        };
        match work.run(
            range.clone(),
            &mut asset,
            &mut denoiser,
            sink,
            stop,
            observe,
        ) {
            Ok(done) => {
                report.rendered += u64::from(asset.views_rendered);
                report.skipped += u64::from(asset.views_skipped);
                if !done {
                    report.stopped = true;
                }
            }
            Err(e) if stops_the_job(&e) => return Err(e),
            Err(e) => asset.error = Some(e.to_string()),
        }
        observe(ViewsEvent::Asset(&asset));
        report.assets.push(asset);
        if report.stopped {
            break;
        }
    }
    Ok(report)
}

/// Whether `e` is about writing outputs (or the denoiser): it stops a
/// views job; anything else (a missing or broken asset) stops only its
/// asset.
fn stops_the_job(e: &Error) -> bool {
    matches!(e, Error::Io(_) | Error::Denoise(_))
}

/// What rendering one view took.
struct ViewDone {
    /// Seconds tracing paths.
    render_seconds: f64,
    /// Seconds on the rest (AOVs, denoise, writing, hashing).
    write_seconds: f64,
    /// Samples per pixel it went on from (0: rendered from the start).
    resumed: u64,
    /// Rays cast.
    rays: u64,
    /// Seconds in each wavefront stage.
    stages: StageSeconds,
}

/// One asset's share of a job.
struct AssetWork<'a> {
    job: &'a ViewsJob,
    /// The asset's name (its folder's).
    name: &'a str,
    options: &'a ViewsOptions,
    job_hash: u128,
    path: &'a Path,
    dir: PathBuf,
}

impl AssetWork<'_> {
    /// The file names of view `i`, colour first.
    fn files(&self, i: u32) -> Vec<String> {
        let o = &self.job.outputs;
        let n = format!("{i:0w$}", w = name_width(self.job.view_count()));
        let mut files = Vec::new();
        if o.png {
            files.push(format!("{n}.png"));
        }
        if o.exr {
            files.push(format!("{n}.exr"));
        }
        for aov in o.aovs.iter() {
            match aov {
                Aov::Alpha => {} // a channel of the colour files
                Aov::ObjectId => files.push(format!("{n}.object_id.png")),
                _ => files.push(format!("{n}.{}.exr", aov.name())),
            }
        }
        files
    }

    /// The asset's files beside its views: the camera files, and the
    /// object-id legend when the job writes object ids.
    fn asset_files(&self) -> Vec<&'static str> {
        let mut files = vec!["transforms.json", "cameras.json"];
        if self.job.outputs.aovs.contains(Aov::ObjectId) {
            files.push(LEGEND);
        }
        files
    }

    fn record_path(&self, i: u32) -> PathBuf {
        let w = name_width(self.job.view_count());
        self.dir.join("manifest").join(format!("{i:0w$}.json"))
    }

    /// Whether view `i`'s record says it is finished with these hashes,
    /// and its files are there with the hashes recorded.
    fn finished(&self, i: u32, asset_hash: u128) -> bool {
        let Ok(text) = std::fs::read_to_string(self.record_path(i)) else {
            return false;
        };
        let Ok(record) = serde_json::from_str::<serde_json::Value>(&text) else {
            return false;
        };
        let hex = |k: &str| record.get(k).and_then(|v| v.as_str()).map(str::to_string);
        if hex("job") != Some(format!("{:032x}", self.job_hash))
            || hex("asset") != Some(format!("{asset_hash:032x}"))
        {
            return false;
        }
        let Some(files) = record.get("files").and_then(|f| f.as_object()) else {
            return false;
        };
        let wanted = self.files(i);
        files.len() == wanted.len()
            && wanted.iter().all(|name| {
                let recorded = files.get(name).and_then(|v| v.as_str());
                recorded.is_some() && recorded == file_hash(&self.dir.join(name)).as_deref()
            })
    }

    /// Render the views `range` not yet finished. Returns false when
    /// `stop` ended it early.
    fn run(
        &self,
        range: std::ops::Range<u32>,
        report: &mut AssetReport,
        denoiser: &mut Option<Denoiser>,
        sink: &mut Sink,
        stop: &(dyn Fn() -> bool + Sync),
        observe: &mut dyn FnMut(ViewsEvent),
    ) -> Result<bool> {
        let hash = asset_hash(self.path)?;
        let files = matches!(sink, Sink::Files);
        let todo: Vec<u32> = (range.clone())
            .filter(|&i| !files || !self.finished(i, hash))
            .collect();
        let have_cameras =
            !files || (self.asset_files().iter()).all(|f| self.dir.join(f).is_file());
        for i in range.clone().filter(|i| !todo.contains(i)) {
            report.views_skipped += 1;
            observe(ViewsEvent::View {
                asset: &report.name,
                view: i,
                skipped: true,
                render_seconds: 0.0,
                write_seconds: 0.0,
            });
        }
        if todo.is_empty() && have_cameras {
            return Ok(true);
        }
        let t = Instant::now();
        let (mut scene, lo, hi) = load_asset(self.path)?;
        scene.lights.extend(self.job.lights.iter().cloned());
        report.load_seconds = t.elapsed().as_secs_f64();
        report.triangles = scene.triangles.len();
        let job = self.job;
        let n = normalisation(lo, hi, job.normalize);
        let (wlo, whi) = ((lo - n.centre) * n.scale, (hi - n.centre) * n.scale);
        let camera_seed = |i: u32| derive(self.job_hash, hash, i, b"camera");
        let poses = poses(job, wlo, whi, &camera_seed);
        if files {
            self.write_cameras(&poses, &scene)?;
        }
        if todo.is_empty() {
            return Ok(true);
        }
        let t = Instant::now();
        let mut lighting = None;
        if !job.environments.is_empty() {
            let pick = self.lighting(hash, todo[0]);
            scene.environment = Some(self.environment(pick));
            lighting = Some(pick);
        }
        let settings = self.settings(&scene);
        let mut renderer = Renderer::new(&scene, &settings)?;
        let objects: Vec<(u32, String)> = match files {
            true => Vec::new(),
            false => (scene.objects.legend())
                .map(|(id, name)| (id, name.to_string()))
                .collect(),
        };
        report.build_seconds = t.elapsed().as_secs_f64();
        for &i in &todo {
            if stop() {
                return Ok(false);
            }
            if !job.environments.is_empty() {
                let pick = self.lighting(hash, i);
                match lighting {
                    Some(l) if l == pick => {}
                    // Only the rotation changes: the environment's tables
                    // stay (the same bits as building them again).
                    Some((k, _)) if k == pick.0 => {
                        if let Some(env) = &mut scene.environment {
                            env.rotation_deg = pick.1;
                        }
                        renderer.turn_environment(pick.1);
                    }
                    _ => {
                        scene.environment = Some(self.environment(pick));
                        renderer.relight(&scene);
                    }
                }
                lighting = Some(pick);
            }
            let view = View {
                index: i,
                pose: &poses[i as usize],
                n: &n,
                seed: view_seed(self.job_hash, hash, i),
                asset_hash: hash,
                transparent: scene.has_transparent_background(),
                objects: &objects,
            };
            let Some(done) = self.view(&mut renderer, &view, denoiser, sink, stop)? else {
                return Ok(false);
            };
            report.views_rendered += 1;
            report.views_resumed += u32::from(done.resumed > 0);
            report.render_seconds += done.render_seconds;
            report.write_seconds += done.write_seconds;
            report.rays += done.rays;
            report.stages += done.stages;
            report.texture_seconds = report.stages.textures();
            observe(ViewsEvent::View {
                asset: &report.name,
                view: i,
                skipped: false,
                render_seconds: done.render_seconds,
                write_seconds: done.write_seconds,
            });
        }
        Ok(true)
    }

    /// The asset's files about all its views: the camera files, and the
    /// object-id legend when the views have object ids.
    fn write_cameras(&self, poses: &[Pose], scene: &Scene) -> Result<()> {
        std::fs::create_dir_all(self.dir.join("manifest"))
            .map_err(|e| crate::fs::FileError::new(&self.dir, e))?;
        let colour: Vec<String> = (0..self.job.view_count())
            .map(|i| self.files(i)[0].clone())
            .collect();
        write_text(
            &self.dir.join("transforms.json"),
            &transforms_json(poses, &colour),
        )?;
        write_text(&self.dir.join("cameras.json"), &opencv_json(poses, &colour))?;
        if self.job.outputs.aovs.contains(Aov::ObjectId) {
            write_text(&self.dir.join(LEGEND), &legend_json(&scene.objects))?;
        }
        Ok(())
    }

    /// The render settings of this asset's views.
    fn settings(&self, scene: &Scene) -> RenderSettings {
        let r = &self.job.render;
        let mut s = RenderSettings::for_scene(scene);
        s.width = r.width;
        s.height = r.height;
        s.spp = r.spp;
        s.max_depth = r.max_depth.unwrap_or(scene.max_depth);
        s.integrator = r.integrator.unwrap_or(s.integrator);
        s.threads = self.options.threads;
        s.engine = self.options.engine;
        s.batch_size = self.options.batch_size.unwrap_or(s.batch_size);
        s.aovs = self.job.outputs.aovs;
        s.adaptive = r.adaptive;
        // A transparent background — the asset's own, or any of the job's
        // environments (`visible = false`) — writes the coverage as the
        // colour's alpha, as `render` does.
        let envs = &self.job.environments;
        if (envs.is_empty() && scene.has_transparent_background())
            || envs.iter().any(|e| !e.visible)
        {
            s.aovs = s.aovs.with(Aov::Alpha);
        }
        if r.denoise {
            s.aovs = s.aovs.union(AovSet::DENOISE);
        }
        s
    }

    /// The lighting of view `i`: a seeded choice among the job's
    /// environments, and its rotation (degrees; a seeded angle when the job
    /// asks, else the environment's own).
    fn lighting(&self, asset_hash: u128, i: u32) -> (usize, f32) {
        let envs = &self.job.environments;
        let mut u =
            super::views_cameras::Stream::new(derive(self.job_hash, asset_hash, i, b"light"));
        let k = ((u.uniform() * envs.len() as f32) as usize).min(envs.len() - 1);
        let rotation = match self.job.random_rotation {
            true => 360.0 * u.uniform(),
            false => envs[k].rotation_deg,
        };
        (k, rotation)
    }

    /// The environment of a [`lighting`](Self::lighting) choice.
    fn environment(&self, (k, rotation): (usize, f32)) -> crate::scene::environment::Environment {
        let mut env = self.job.environments[k].clone();
        env.rotation_deg = rotation;
        env
    }

    /// Render one view and write it (or hand it to the sink's function);
    /// `None` when `stop` ended it (nothing written) or the function said
    /// to end.
    fn view(
        &self,
        renderer: &mut Renderer,
        view: &View,
        denoiser: &mut Option<Denoiser>,
        sink: &mut Sink,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<ViewDone>> {
        let (w, h) = (self.job.render.width, self.job.render.height);
        renderer.set_view(&view.n.camera(view.pose), view.seed);
        let t = Instant::now();
        let files = matches!(sink, Sink::Files);
        let Some((film, resumed, counters)) = self.render(renderer, view, files, stop)? else {
            return Ok(None);
        };
        let render_seconds = t.elapsed().as_secs_f64();
        let done = |write_seconds| ViewDone {
            render_seconds,
            write_seconds,
            resumed,
            rays: counters.rays,
            stages: counters.stages,
        };
        let t = Instant::now();
        let aovs = film.aov_images();
        let layer = |a: Aov| aovs.iter().find(|(x, _)| *x == a).map(|(_, p)| &p[..]);
        let mut rgb = film.to_rgb();
        if let Some(d) = denoiser {
            let aux = Aux {
                albedo: layer(Aov::Albedo).expect("denoise accumulates albedo"),
                normal: layer(Aov::Normal).expect("denoise accumulates normal"),
            };
            rgb = d.denoise(w, h, &rgb, Some(aux))?;
        }
        if let Sink::Memory(each) = sink {
            let streamed = StreamedView {
                asset: self.name,
                file: self.path,
                view: view.index,
                camera: view.pose,
                normalisation: view.n,
                film: &film,
                aovs: (aovs.iter())
                    // (Adaptive sampling's variance only where it was asked for.)
                    .filter(|(aov, _)| {
                        *aov != Aov::Variance || self.job.outputs.aovs.contains(Aov::Variance)
                    })
                    .map(|(aov, pixels)| (*aov, self.in_job_world(*aov, pixels, view)))
                    .collect(),
                rgb: &rgb,
                objects: view.objects,
            };
            let write_seconds = t.elapsed().as_secs_f64();
            return Ok(each(streamed)?.then(|| done(write_seconds)));
        }
        let files = self.files(view.index);
        let mut names = files.iter();
        let o = &self.job.outputs;
        let alpha = layer(Aov::Alpha);
        if o.png {
            let path = self.dir.join(names.next().expect("named"));
            let view_transform = ViewTransform::default();
            match alpha {
                // Straight colour, as PNG defines it: the mean of the
                // samples that hit, where the background is transparent.
                Some(a) if view.transparent => {
                    crate::output::write_rgba_png(&path, (w, h), &rgb, a, view_transform)?
                }
                // An opaque background is part of the colour.
                Some(a) => {
                    crate::output::write_rgba_png_straight(&path, (w, h), &rgb, a, view_transform)?
                }
                None => {
                    crate::output::write_image_viewed(&path, w, h, &rgb, ViewTransform::default())?
                }
            }
        }
        if o.exr {
            let path = self.dir.join(names.next().expect("named"));
            let layers: Vec<ExrLayer> = (alpha.iter())
                .map(|a| {
                    let (name, channels) = crate::output::ALPHA_LAYER;
                    ExrLayer {
                        name,
                        channels,
                        pixels: a,
                    }
                })
                .collect();
            crate::output::write_exr_layers(&path, w, h, &rgb, &layers)?;
        }
        for aov in o.aovs.iter().filter(|a| *a != Aov::Alpha) {
            let path = self.dir.join(names.next().expect("named"));
            let pixels = layer(aov).expect("accumulated");
            match aov {
                Aov::ObjectId => crate::output::write_id_png(&path, w, h, pixels)?,
                _ => self.write_aov(&path, aov, &self.in_job_world(aov, pixels, view))?,
            }
        }
        self.write_record(view, &files)?;
        // The view is finished: its checkpoint is of no more use.
        let _ = std::fs::remove_file(self.checkpoint_path(view.index));
        Ok(Some(done(t.elapsed().as_secs_f64())))
    }

    /// View `i`'s checkpoint: its film so far, `manifest/NNNN.wtacc`.
    fn checkpoint_path(&self, i: u32) -> PathBuf {
        self.record_path(i)
            .with_extension(crate::output::PARTIAL_EXTENSION)
    }

    /// Trace a view's samples, in passes, from its checkpoint when there
    /// is one of this very view (same job, asset, view and seed, size and
    /// AOVs); the checkpoint is saved every
    /// [`checkpoint_every`](ViewsOptions::checkpoint_every) and when
    /// `stop` ends the view (`None`). Without `checkpoints` ([`stream`])
    /// none is read or written. Returns the film, the samples per pixel
    /// it resumed with and what tracing it took this run (rays, stages).
    fn render(
        &self,
        renderer: &Renderer,
        view: &View,
        checkpoints: bool,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<(crate::film::Film, u64, crate::integrator::Counters)>> {
        let spp = self.job.render.spp;
        if renderer.settings().adaptive.is_some() {
            // Each round's pixels follow from the whole film so far: an
            // adaptive view keeps no checkpoint (a stopped one starts
            // again).
            let mut film = renderer.new_film();
            let traced = renderer.render_adaptive_or_stop(&mut film, stop);
            return Ok(traced.map(|t| (film, 0, t)));
        }
        let path = self.checkpoint_path(view.index);
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        for part in [self.job_hash, view.asset_hash, u128::from(view.index)] {
            h.update(&part.to_le_bytes());
        }
        h.update(&view.seed.to_le_bytes());
        let meta = AccMeta {
            settings_hash: h.digest128(),
            spp: Some(spp),
            shard: None,
        };
        let target = 0..spp;
        let mut film = (checkpoints.then(|| Film::load_with_meta(&path, Some(meta.settings_hash))))
            .and_then(|r| r.ok())
            .filter(|(f, m)| {
                m.spp == Some(spp)
                    && crate::run::session::check_resumable(f, renderer.settings(), &target).is_ok()
            })
            .map_or_else(|| renderer.new_film(), |(f, _)| f);
        let resumed = film.samples_per_pixel();
        let (mut saved, mut since) = (resumed, Instant::now());
        let save = |film: &crate::film::Film, saved: &mut u64| -> Result<()> {
            if checkpoints && film.samples_per_pixel() > *saved {
                film.save_with_meta(&path, &meta)?;
                *saved = film.samples_per_pixel();
            }
            Ok(())
        };
        let (mut per_sample, mut traced) = (None::<f64>, crate::integrator::Counters::default());
        while let Some(gap) = crate::run::session::first_gap(&film.ranges, &target) {
            // Passes of about PASS_SECONDS (one sample first, to measure).
            let n = match (self.options.pass_samples, per_sample) {
                (Some(n), _) => n.max(1),
                (None, None) => 1,
                (None, Some(p)) => (PASS_SECONDS / p).clamp(1.0, f64::from(spp)) as u32,
            };
            let n = n.min(gap.end - gap.start);
            let t = Instant::now();
            let pass = match stop() {
                true => None,
                false => renderer.render_samples_or_stop(gap.start..gap.start + n, &mut film, stop),
            };
            let Some(counters) = pass else {
                save(&film, &mut saved)?;
                return Ok(None);
            };
            traced += counters;
            per_sample = Some(t.elapsed().as_secs_f64() / f64::from(n));
            let more = crate::run::session::first_gap(&film.ranges, &target).is_some();
            if more && since.elapsed() >= self.options.checkpoint_every {
                save(&film, &mut saved)?;
                since = Instant::now();
            }
        }
        Ok(Some((film, resumed, traced)))
    }

    /// AOV `aov` of a view as the views give it: depths in the job's world
    /// units (the film's times the normalisation's scale), normals in the
    /// world's axes or, when the job asks, the camera's (OpenCV: x right,
    /// y down, z forward); the others as accumulated.
    fn in_job_world(&self, aov: Aov, pixels: &[[f32; 3]], view: &View) -> Vec<[f32; 3]> {
        let (s, p) = (view.n.scale, view.pose);
        match aov {
            _ if aov.def().length => pixels.iter().map(|d| [d[0] * s, d[1], d[2]]).collect(),
            Aov::Normal if self.job.outputs.camera_normals => (pixels.iter())
                .map(|n| {
                    let n = Vec3::from_array(*n);
                    [p.right.dot(n), -p.up.dot(n), p.forward.dot(n)]
                })
                .collect(),
            _ => pixels.to_vec(),
        }
    }

    /// Write AOV `aov` of a view (as [`in_job_world`](Self::in_job_world)
    /// gives it) as an EXR: depth (`Z`), normal (`X`, `Y`, `Z`), albedo and
    /// variance (`R`, `G`, `B`), with its convention in the header.
    fn write_aov(&self, path: &Path, aov: Aov, pixels: &[[f32; 3]]) -> Result<()> {
        let (w, h) = (self.job.render.width, self.job.render.height);
        let plane = |k: usize| pixels.iter().map(|v| v[k]).collect::<Vec<f32>>();
        let (_, channels) = aov.def().layer;
        let note = match aov {
            Aov::Normal if self.job.outputs.camera_normals => {
                "normal: shading normal at the first non-specular hit, camera axes (OpenCV: x right, y down, z forward), mean over samples, not renormalised, 0 where none"
            }
            _ => aov.def().meaning,
        };
        let planes = (0..channels.len()).map(plane).collect();
        write_exr_channels(path, (w, h), channels, planes, note)
    }

    /// The view's record: written last, so it exists only when every file
    /// of the view is whole.
    fn write_record(&self, view: &View, files: &[String]) -> Result<()> {
        let mut hashes = serde_json::Map::new();
        for name in files {
            let hash = file_hash(&self.dir.join(name)).ok_or_else(|| {
                Error::Settings(format!(
                    "{}: written but cannot be read back",
                    self.dir.join(name).display()
                ))
            })?;
            hashes.insert(name.clone(), hash.into());
        }
        let record = serde_json::json!({
            "view": view.index,
            "job": format!("{:032x}", self.job_hash),
            "asset": format!("{:032x}", view.asset_hash),
            "seed": view.seed,
            "files": hashes,
        });
        write_text(&self.record_path(view.index), &(record.to_string() + "\n"))
    }
}

/// The object-id legend's file name, per asset.
pub const LEGEND: &str = "objects.json";

/// The object-id legend of a scene: `{"background": 0, "objects": [{"id":
/// 1, "name": ...}, ...]}`, ids from 1 in the scene's order (what the
/// `object_id.png` files hold).
fn legend_json(objects: &crate::scene::Objects) -> String {
    let list: Vec<serde_json::Value> = objects
        .legend()
        .map(|(id, name)| serde_json::json!({ "id": id, "name": name }))
        .collect();
    let doc = serde_json::json!({ "background": 0, "objects": list });
    serde_json::to_string_pretty(&doc).expect("JSON") + "\n"
}

/// A view to render.
struct View<'a> {
    index: u32,
    pose: &'a Pose,
    n: &'a Normalisation,
    seed: u64,
    asset_hash: u128,
    /// The asset's object-id legend (filled for [`stream`] only).
    objects: &'a [(u32, String)],
    /// Whether the view's background is transparent (its environment is
    /// not visible): the colour PNG is then straight, divided by the alpha.
    transparent: bool,
}

/// The hex xxh3-128 hash of a file's bytes; `None` when it cannot be read.
pub fn file_hash(path: &Path) -> Option<String> {
    let bytes = std::fs::read(path).ok()?;
    Some(format!("{:032x}", xxhash_rust::xxh3::xxh3_128(&bytes)))
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    Ok(write_atomic(path, |w| w.write_all(text.as_bytes()))?)
}

/// Write a single-part float EXR of the named channels, atomically, with
/// `note` as its `wavetrace` header attribute.
fn write_exr_channels(
    path: &Path,
    (width, height): (u32, u32),
    names: &[&str],
    planes: Vec<Vec<f32>>,
    note: &str,
) -> Result<()> {
    use exr::prelude::*;
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (name, plane) in names.iter().zip(planes) {
        list.push(AnyChannel::new(*name, FlatSamples::F32(plane)));
    }
    let mut attributes = LayerAttributes::default();
    attributes.other.insert(
        Text::from("wavetrace"),
        AttributeValue::Text(Text::from(note)),
    );
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    let layer = Layer::new(
        (width as usize, height as usize),
        attributes,
        encoding,
        AnyChannels::sort(list),
    );
    let image = Image::from_layer(layer);
    Ok(write_atomic(path, |w| {
        let mut buf = std::io::Cursor::new(Vec::new());
        image
            .write()
            .to_buffered(&mut buf)
            .map_err(std::io::Error::other)?;
        w.write_all(buf.get_ref())
    })?)
}
