//! The front end of `wavetrace views` jobs: a TOML job file (the assets,
//! their normalisation, the cameras, the lighting, the render settings and
//! the outputs) and the JSON files of explicit cameras, read into a
//! [`ViewsJob`]. Errors name the file, the line and column (TOML) or JSON
//! path, and the field. The format is described in `docs/views.md`.

use super::environment::{self, Environment, EnvironmentFile};
use super::{Adaptive, AovSet, Integrator, SceneError};
use glam::Vec3;
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The default image width and height of a view.
pub const DEFAULT_SIZE: u32 = 512;
/// The default samples per pixel of a view.
pub const DEFAULT_SPP: u32 = 64;
/// The default vertical field of view of generated cameras, degrees.
pub const DEFAULT_VFOV_DEG: f32 = 40.0;
/// The most views a job may ask of each asset.
pub const MAX_VIEWS: u32 = 10_000_000;

/// A views job, checked: everything `wavetrace views` needs but the
/// assets' contents.
#[derive(Clone, Debug)]
pub struct ViewsJob {
    /// The job file, for messages (or a label for a job made from flags).
    pub file: String,
    /// The asset files, in the job's order (globs expanded and sorted, list
    /// files read). A file may be missing or broken: it is reported and
    /// skipped when its turn comes.
    pub assets: Vec<PathBuf>,
    /// Centre each asset on the origin and scale it to fit the cube
    /// `[-½, ½]³` (cameras, depths and camera files are then in those units).
    pub normalize: bool,
    /// Where the views look from.
    pub cameras: CameraSet,
    /// The point generated cameras look at (in the normalised world when
    /// `normalize`); `None`: the centre of the asset's bounds.
    pub target: Option<Vec3>,
    /// The environments, each loaded once; each view takes one (a seeded
    /// choice when there are several). Empty: each asset's own light (a
    /// TOML scene's environment and emitters; the default sky for an
    /// asset that has no emitter).
    pub environments: Vec<Environment>,
    /// Suns added to every view's lighting (`[[light]]`, type `sun`).
    pub lights: Vec<super::punctual::PunctualLight>,
    /// Turn the environment by a seeded random angle about +Y per view.
    pub random_rotation: bool,
    /// The render settings.
    pub render: ViewsRender,
    /// What each view writes.
    pub outputs: ViewsOutputs,
}

/// The render settings of a job's views.
#[derive(Clone, PartialEq)]
pub struct ViewsRender {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Maximum path depth; `None`: the asset's own.
    pub max_depth: Option<u32>,
    /// The estimator; `None`: the renderer's default.
    pub integrator: Option<Integrator>,
    /// The job's seed: every view's seed is derived from it, the job and
    /// the asset's bytes.
    pub seed: u64,
    /// Denoise the colour image (Open Image Denoise).
    pub denoise: bool,
    /// Adaptive sampling (`noise_threshold`, `min_spp`); `None`: every
    /// pixel takes `spp` samples.
    pub adaptive: Option<Adaptive>,
}

/// The job's hash ([`ViewsJob::settings_hash`]) is of these words: a job
/// without adaptive sampling writes the words of before it existed (its
/// views keep their seeds and bytes).
impl std::fmt::Debug for ViewsRender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("ViewsRender");
        d.field("width", &self.width)
            .field("height", &self.height)
            .field("spp", &self.spp)
            .field("max_depth", &self.max_depth)
            .field("integrator", &self.integrator)
            .field("seed", &self.seed)
            .field("denoise", &self.denoise);
        if let Some(a) = &self.adaptive {
            d.field("adaptive", a);
        }
        d.finish()
    }
}

/// What each view of a job writes.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewsOutputs {
    /// The colour as an 8-bit sRGB PNG.
    pub png: bool,
    /// The colour as a linear float EXR.
    pub exr: bool,
    /// The AOVs: each an EXR of its own, the object ids a 16-bit PNG,
    /// the alpha a channel of the colour files.
    pub aovs: AovSet,
    /// Write the normals in the camera's frame (OpenCV axes) instead of
    /// the world's.
    pub camera_normals: bool,
}

/// Where a job's views look from.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSet {
    /// `views` per elevation, at azimuths `azimuth + 360°·k/views`.
    Orbit {
        /// Views per elevation.
        views: u32,
        /// Elevations above the horizontal plane, degrees.
        elevations_deg: Vec<f32>,
        /// The first view's azimuth, degrees (0: from +Z).
        azimuth_deg: f32,
        /// Distance from the target; `None`: the asset's bounding sphere
        /// fills the field of view.
        distance: Option<f32>,
        /// Vertical field of view, degrees.
        vfov_deg: f32,
    },
    /// `views` directions spread evenly over the sphere (a Fibonacci
    /// lattice).
    Fibonacci {
        /// How many.
        views: u32,
        /// As the orbit's.
        distance: Option<f32>,
        /// Vertical field of view, degrees.
        vfov_deg: f32,
    },
    /// `views` seeded random directions, uniform over the sphere, at
    /// seeded distances and fields of view within the ranges.
    Random {
        /// How many.
        views: u32,
        /// The range of distances; `None`: 1 to 1.5 times the framing distance.
        distance: Option<[f32; 2]>,
        /// The range of vertical fields of view, degrees.
        vfov_deg: [f32; 2],
    },
    /// Cameras given one by one (a JSON file).
    Explicit(Vec<ExplicitCamera>),
}

/// A camera of a JSON camera file.
#[derive(Clone, Debug, PartialEq)]
pub struct ExplicitCamera {
    /// Camera to world, rows of a 4×4 matrix, the OpenGL/NeRF axes (the
    /// camera looks down its −Z, +Y up, +X right).
    pub camera_to_world: [[f32; 4]; 4],
    /// Its intrinsics, independent of the image's size.
    pub intrinsics: Intrinsics,
}

/// A camera file's intrinsics, as fractions so that they hold at any
/// image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Horizontal field of view, radians (of a centred image).
    pub angle_x: f32,
    /// `fl_y / fl_x` (1: square pixels).
    pub focal_aspect_y: f32,
    /// The principal point's offset from the image's centre, as fractions
    /// of the image's width and height.
    pub principal_offset: [f32; 2],
}

impl CameraSet {
    /// How many views the cameras make of each asset.
    pub fn len(&self) -> u32 {
        match self {
            CameraSet::Orbit {
                views,
                elevations_deg,
                ..
            } => views * elevations_deg.len() as u32,
            CameraSet::Fibonacci { views, .. } | CameraSet::Random { views, .. } => *views,
            CameraSet::Explicit(c) => c.len() as u32,
        }
    }

    /// Whether there are no views.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl ViewsJob {
    /// Read and check the job file at `path`; its relative paths are
    /// relative to its directory.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| {
            super::builder::Origin::file(&file).error(format!("cannot read the job file: {e}"))
        })?;
        Self::parse(&text, &file)
    }

    /// Parse job text; `file` names it in errors and is where relative
    /// paths start.
    pub fn parse(text: &str, file: &str) -> Result<Self, SceneError> {
        let t = Text { text, file };
        let raw: JobFile = toml::from_str(text).map_err(|e| t.toml_error(&e))?;
        let base = Path::new(file)
            .parent()
            .unwrap_or(Path::new(""))
            .to_path_buf();
        let (assets, normalize) = assets(&t, &raw.assets, &base)?;
        let (cameras, target) = cameras(&t, raw.cameras.as_ref(), &base)?;
        let mut environments = Vec::new();
        for (i, e) in raw.environment.iter().enumerate() {
            let env = environment::from_file(Some(e), file).map_err(|(span, field, m)| {
                let field = field.replacen("environment", &format!("environment[{i}]"), 1);
                t.err(span, &field, m)
            })?;
            environments.extend(env);
        }
        let random_rotation = raw.lighting.as_ref().is_some_and(|l| l.random_rotation);
        let lights = suns(&t, &raw.lights)?;
        Ok(Self {
            file: file.to_string(),
            assets,
            normalize,
            cameras,
            target,
            environments,
            lights,
            random_rotation,
            render: render(&t, raw.render.as_ref())?,
            outputs: outputs(&t, raw.outputs.as_ref())?,
        })
    }

    /// How many views each asset gets.
    pub fn view_count(&self) -> u32 {
        self.cameras.len()
    }

    /// A 128-bit hash of everything in the job that changes a view's
    /// pixels (not the asset list or the outputs): with the asset's bytes
    /// and the view's index, what a view's seed is derived from.
    pub fn settings_hash(&self) -> u128 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        let words = format!(
            "{:?}",
            (
                self.normalize,
                &self.cameras,
                self.target,
                self.random_rotation,
                &self.render
            )
        );
        h.update(words.as_bytes());
        for env in &self.environments {
            env.hash_into(&mut h);
        }
        // (Jobs without lights hash as before lights existed.)
        for light in &self.lights {
            light.hash_into(&mut h);
        }
        h.digest128()
    }
}

/// The job's `[[light]]`s: suns only (a sun has no position, so it means
/// the same for every asset, normalised or not).
fn suns(
    t: &Text,
    raw: &[Spanned<super::punctual::LightFile>],
) -> Result<Vec<super::punctual::PunctualLight>, SceneError> {
    let mut out = Vec::new();
    for (k, l) in raw.iter().enumerate() {
        let light = super::punctual::from_file(k, l.get_ref())
            .map_err(|(span, field, m)| t.err(span, &field, m))?;
        if !matches!(light.shape, super::punctual::LightShape::Sun { .. }) {
            return Err(t.err(
                l.span(),
                &format!("light[{k}].type"),
                "a views job's lights are suns: a point or spot light's place would depend on each asset (put it in a TOML scene that places the asset)",
            ));
        }
        out.push(light);
    }
    Ok(out)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JobFile {
    assets: Spanned<AssetsFile>,
    cameras: Option<Spanned<CamerasFile>>,
    #[serde(default)]
    environment: Vec<Spanned<EnvironmentFile>>,
    #[serde(default, rename = "light")]
    lights: Vec<Spanned<super::punctual::LightFile>>,
    lighting: Option<LightingFile>,
    render: Option<RenderFile>,
    outputs: Option<OutputsFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AssetsFile {
    #[serde(default)]
    files: Vec<Spanned<String>>,
    list: Option<Spanned<String>>,
    #[serde(default)]
    normalize: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CamerasFile {
    kind: Spanned<String>,
    views: Option<Spanned<u32>>,
    elevations: Option<Spanned<Vec<f32>>>,
    azimuth: Option<Spanned<f32>>,
    distance: Option<Spanned<OneOrTwo>>,
    fov: Option<Spanned<OneOrTwo>>,
    target: Option<Spanned<[f32; 3]>>,
    file: Option<Spanned<String>>,
}

/// A number, or a range `[low, high]`.
#[derive(Clone, Copy, Deserialize)]
#[serde(untagged)]
enum OneOrTwo {
    One(f32),
    Two([f32; 2]),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightingFile {
    #[serde(default)]
    random_rotation: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderFile {
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    spp: Option<Spanned<u32>>,
    max_depth: Option<u32>,
    integrator: Option<Spanned<String>>,
    seed: Option<u64>,
    #[serde(default)]
    denoise: bool,
    noise_threshold: Option<Spanned<f32>>,
    min_spp: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputsFile {
    color: Option<Spanned<Vec<String>>>,
    aov: Option<Spanned<Vec<String>>>,
    normals: Option<Spanned<String>>,
}

/// The job's text, for placing errors.
struct Text<'a> {
    text: &'a str,
    file: &'a str,
}

impl Text<'_> {
    /// The error `message` about `field`, written at `span`.
    fn err(&self, span: Range<usize>, field: &str, message: impl Into<String>) -> SceneError {
        let (line, column) = line_col(self.text, span.start);
        super::builder::Origin {
            file: self.file.to_string(),
            line,
            column,
            field: Some(field.to_string()),
        }
        .error(message)
    }

    /// A TOML or serde error at its place, with the field written there.
    fn toml_error(&self, e: &toml::de::Error) -> SceneError {
        let start = e.span().map_or(0, |s| s.start);
        let (line, column) = e.span().map_or((0, 0), |s| line_col(self.text, s.start));
        SceneError {
            file: self.file.to_string(),
            line,
            column,
            field: e.span().and_then(|_| field_at(self.text, start)),
            message: e.message().trim().to_string(),
            mesh: None,
        }
    }
}

/// 1-based line and column of byte `offset` in `text`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The dotted field at byte `offset`: the table whose header comes last
/// before it, and the key written there (if any).
fn field_at(text: &str, offset: usize) -> Option<String> {
    let before = &text[..offset.min(text.len())];
    let header = before
        .lines()
        .filter_map(|l| {
            let l = l.trim();
            l.starts_with('[')
                .then(|| l.trim_matches(|c| c == '[' || c == ']').trim().to_string())
        })
        .next_back();
    let rest = &text[offset.min(text.len())..];
    let key: String = rest
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '-')
        .collect();
    let key = (!key.is_empty() && rest[key.len()..].trim_start().starts_with('=')).then_some(key);
    match (header, key) {
        (Some(h), Some(k)) => Some(format!("{h}.{k}")),
        (Some(h), None) => Some(h),
        (None, k) => k,
    }
}

/// The asset files of `[assets]` and whether to normalise them.
fn assets(
    t: &Text,
    raw: &Spanned<AssetsFile>,
    base: &Path,
) -> Result<(Vec<PathBuf>, bool), SceneError> {
    let a = raw.get_ref();
    let mut out = Vec::new();
    for (i, f) in a.files.iter().enumerate() {
        let pattern = base.join(f.get_ref());
        let field = format!("assets.files[{i}]");
        if f.get_ref().is_empty() {
            return Err(t.err(f.span(), &field, "an empty file name"));
        }
        match expand_glob(&pattern) {
            None => out.push(pattern),
            Some(found) if found.is_empty() => {
                return Err(t.err(
                    f.span(),
                    &field,
                    format!("no file matches {:?}", f.get_ref()),
                ));
            }
            Some(found) => out.extend(found),
        }
    }
    if let Some(list) = &a.list {
        let path = base.join(list.get_ref());
        let text = std::fs::read_to_string(&path).map_err(|e| {
            t.err(
                list.span(),
                "assets.list",
                format!("cannot read {}: {e}", path.display()),
            )
        })?;
        out.extend(read_list(&text, path.parent().unwrap_or(Path::new(""))));
    }
    if out.is_empty() {
        return Err(t.err(raw.span(), "assets", "no assets: give `files` or `list`"));
    }
    Ok((out, a.normalize))
}

/// The files of a list file's `text`: one path a line, relative to `dir`;
/// blank lines and lines starting with `#` skipped.
pub fn read_list(text: &str, dir: &Path) -> Vec<PathBuf> {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| dir.join(l))
        .collect()
}

/// The files matching `pattern` (`*` and `?` within a name, `**` any
/// number of directories), sorted; `None` when it has no wildcard.
pub fn expand_glob(pattern: &Path) -> Option<Vec<PathBuf>> {
    let text = pattern.to_string_lossy();
    if !text.contains(['*', '?']) {
        return None;
    }
    let mut parts: Vec<String> = Vec::new();
    let mut root = PathBuf::new();
    let mut wild = false;
    for c in pattern.components() {
        let s = c.as_os_str().to_string_lossy().into_owned();
        wild |= s.contains(['*', '?']);
        if wild {
            parts.push(s);
        } else {
            root.push(c);
        }
    }
    let mut found = Vec::new();
    let start = if root.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        root.clone()
    };
    glob_walk(&start, &root, &parts, &mut found);
    found.sort();
    found.dedup();
    Some(found)
}

/// The files under `dir` (named from `shown`) matching the pattern
/// components `parts`.
fn glob_walk(dir: &Path, shown: &Path, parts: &[String], found: &mut Vec<PathBuf>) {
    let Some((first, rest)) = parts.split_first() else {
        if dir.is_file() {
            found.push(shown.to_path_buf());
        }
        return;
    };
    if first == "**" {
        glob_walk(dir, shown, rest, found);
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut names: Vec<String> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    for name in names {
        let (path, next) = (dir.join(&name), shown.join(&name));
        if first == "**" {
            if path.is_dir() && !name.starts_with('.') {
                glob_walk(&path, &next, parts, found);
            }
        } else if wildcard_match(first.as_bytes(), name.as_bytes()) {
            glob_walk(&path, &next, rest, found);
        }
    }
}

/// Whether `name` matches `pattern` (`*`: any run, `?`: any one byte).
fn wildcard_match(pattern: &[u8], name: &[u8]) -> bool {
    match pattern.split_first() {
        None => name.is_empty(),
        Some((b'*', rest)) => (0..=name.len()).any(|k| wildcard_match(rest, &name[k..])),
        Some((b'?', rest)) => !name.is_empty() && wildcard_match(rest, &name[1..]),
        Some((c, rest)) => name.first() == Some(c) && wildcard_match(rest, &name[1..]),
    }
}

/// The cameras of `[cameras]` (an orbit of 12 at 30° when absent) and
/// their target.
fn cameras(
    t: &Text,
    raw: Option<&Spanned<CamerasFile>>,
    base: &Path,
) -> Result<(CameraSet, Option<Vec3>), SceneError> {
    let Some(raw) = raw else {
        return Ok((default_orbit(12), None));
    };
    let c = raw.get_ref();
    let views = match &c.views {
        Some(v) if *v.get_ref() == 0 || *v.get_ref() > MAX_VIEWS => {
            return Err(t.err(
                v.span(),
                "cameras.views",
                format!("must be 1 to {MAX_VIEWS}"),
            ));
        }
        Some(v) => Some(*v.get_ref()),
        None => None,
    };
    let set = camera_set(t, raw, views, base)?;
    if set.len() > MAX_VIEWS {
        return Err(t.err(
            raw.span(),
            "cameras",
            format!("{} views: at most {MAX_VIEWS} per asset", set.len()),
        ));
    }
    let target = match &c.target {
        Some(v) if !v.get_ref().iter().all(|x| x.is_finite()) => {
            return Err(t.err(v.span(), "cameras.target", "must be 3 finite numbers"));
        }
        Some(v) => Some(Vec3::from_array(*v.get_ref())),
        None => None,
    };
    Ok((set, target))
}

/// The camera set `[cameras]` asks for (`views` checked already).
fn camera_set(
    t: &Text,
    raw: &Spanned<CamerasFile>,
    views: Option<u32>,
    base: &Path,
) -> Result<CameraSet, SceneError> {
    let c = raw.get_ref();
    let distance = || {
        one(
            t,
            c.distance.as_ref(),
            "cameras.distance",
            0.0..f32::INFINITY,
        )
    };
    let fov = || one(t, c.fov.as_ref(), "cameras.fov", 0.0..180.0);
    let kind = c.kind.get_ref().as_str();
    let need_views = || {
        views.ok_or_else(|| {
            t.err(
                raw.span(),
                "cameras.views",
                format!("a `{kind}` camera set needs `views`"),
            )
        })
    };
    let unused = |name: &str, span: Option<Range<usize>>| -> Result<(), SceneError> {
        match span {
            Some(span) => Err(t.err(
                span,
                &format!("cameras.{name}"),
                format!("not used by `{kind}` cameras"),
            )),
            None => Ok(()),
        }
    };
    let set = match kind {
        "orbit" => CameraSet::Orbit {
            views: need_views()?,
            elevations_deg: elevations(t, c.elevations.as_ref())?,
            azimuth_deg: finite(t, c.azimuth.as_ref(), "cameras.azimuth")?.unwrap_or(0.0),
            distance: distance()?,
            vfov_deg: fov()?.unwrap_or(DEFAULT_VFOV_DEG),
        },
        "fibonacci" => {
            unused("elevations", c.elevations.as_ref().map(|v| v.span()))?;
            CameraSet::Fibonacci {
                views: need_views()?,
                distance: distance()?,
                vfov_deg: fov()?.unwrap_or(DEFAULT_VFOV_DEG),
            }
        }
        "random" => {
            unused("elevations", c.elevations.as_ref().map(|v| v.span()))?;
            CameraSet::Random {
                views: need_views()?,
                distance: two(
                    t,
                    c.distance.as_ref(),
                    "cameras.distance",
                    0.0..f32::INFINITY,
                )?,
                vfov_deg: two(t, c.fov.as_ref(), "cameras.fov", 0.0..180.0)?
                    .unwrap_or([DEFAULT_VFOV_DEG; 2]),
            }
        }
        "explicit" => {
            for (name, span) in [
                ("views", c.views.as_ref().map(|v| v.span())),
                ("elevations", c.elevations.as_ref().map(|v| v.span())),
                ("distance", c.distance.as_ref().map(|v| v.span())),
                ("fov", c.fov.as_ref().map(|v| v.span())),
            ] {
                unused(name, span)?;
            }
            let Some(file) = &c.file else {
                return Err(t.err(
                    raw.span(),
                    "cameras.file",
                    "`explicit` cameras need `file`, a JSON camera file",
                ));
            };
            CameraSet::Explicit(read_cameras(&base.join(file.get_ref()))?)
        }
        other => {
            return Err(t.err(
                c.kind.span(),
                "cameras.kind",
                format!("unknown camera set {other:?} (known: orbit, fibonacci, random, explicit)"),
            ));
        }
    };
    if kind != "explicit" {
        unused("file", c.file.as_ref().map(|v| v.span()))?;
    }
    Ok(set)
}

/// An orbit of `views` views at 30° elevation, framing the asset.
pub fn default_orbit(views: u32) -> CameraSet {
    CameraSet::Orbit {
        views,
        elevations_deg: vec![30.0],
        azimuth_deg: 0.0,
        distance: None,
        vfov_deg: DEFAULT_VFOV_DEG,
    }
}

fn elevations(t: &Text, raw: Option<&Spanned<Vec<f32>>>) -> Result<Vec<f32>, SceneError> {
    let Some(raw) = raw else {
        return Ok(vec![30.0]);
    };
    let e = raw.get_ref();
    if e.is_empty() || e.iter().any(|x| !(x.is_finite() && x.abs() < 90.0)) {
        return Err(t.err(
            raw.span(),
            "cameras.elevations",
            "must be one or more angles strictly between -90 and 90 degrees",
        ));
    }
    Ok(e.clone())
}

fn finite(t: &Text, raw: Option<&Spanned<f32>>, field: &str) -> Result<Option<f32>, SceneError> {
    match raw {
        Some(v) if !v.get_ref().is_finite() => {
            Err(t.err(v.span(), field, "must be a finite number"))
        }
        v => Ok(v.map(|v| *v.get_ref())),
    }
}

/// One number strictly inside `range`.
fn one(
    t: &Text,
    raw: Option<&Spanned<OneOrTwo>>,
    field: &str,
    range: Range<f32>,
) -> Result<Option<f32>, SceneError> {
    let Some(raw) = raw else {
        return Ok(None);
    };
    match raw.get_ref() {
        OneOrTwo::One(x) if *x > range.start && *x < range.end => Ok(Some(*x)),
        OneOrTwo::One(_) => Err(t.err(
            raw.span(),
            field,
            format!(
                "must be a number strictly between {} and {}",
                range.start, range.end
            ),
        )),
        OneOrTwo::Two(_) => Err(t.err(
            raw.span(),
            field,
            "one number here (ranges are for `random` cameras)",
        )),
    }
}

/// A range `[low, high]` (or one number, `low = high`) strictly inside `range`.
fn two(
    t: &Text,
    raw: Option<&Spanned<OneOrTwo>>,
    field: &str,
    range: Range<f32>,
) -> Result<Option<[f32; 2]>, SceneError> {
    let Some(raw) = raw else {
        return Ok(None);
    };
    let [a, b] = match raw.get_ref() {
        OneOrTwo::One(x) => [*x, *x],
        OneOrTwo::Two(r) => *r,
    };
    let inside = |x: f32| x > range.start && x < range.end;
    if !(inside(a) && inside(b) && a <= b) {
        return Err(t.err(
            raw.span(),
            field,
            format!(
                "must be [low, high] with low <= high, both strictly between {} and {}",
                range.start, range.end
            ),
        ));
    }
    Ok(Some([a, b]))
}

fn render(t: &Text, raw: Option<&RenderFile>) -> Result<ViewsRender, SceneError> {
    let mut out = ViewsRender {
        width: DEFAULT_SIZE,
        height: DEFAULT_SIZE,
        spp: DEFAULT_SPP,
        max_depth: None,
        integrator: None,
        seed: 0,
        denoise: false,
        adaptive: None,
    };
    let Some(r) = raw else {
        return Ok(out);
    };
    for (v, field, slot) in [
        (&r.width, "render.width", &mut out.width),
        (&r.height, "render.height", &mut out.height),
        (&r.spp, "render.spp", &mut out.spp),
    ] {
        if let Some(v) = v {
            if *v.get_ref() == 0 {
                return Err(t.err(v.span(), field, "must be at least 1"));
            }
            *slot = *v.get_ref();
        }
    }
    if let Some(i) = &r.integrator {
        out.integrator = Some(Integrator::from_name(i.get_ref()).ok_or_else(|| {
            t.err(
                i.span(),
                "render.integrator",
                format!(
                    "unknown integrator {:?} (known: {})",
                    i.get_ref(),
                    Integrator::NAMES.join(", ")
                ),
            )
        })?);
    }
    out.max_depth = r.max_depth;
    out.seed = r.seed.unwrap_or(0);
    out.denoise = r.denoise;
    out.adaptive = adaptive(t, r, out.spp)?;
    Ok(out)
}

/// `render.noise_threshold` and `render.min_spp`: adaptive sampling.
fn adaptive(t: &Text, r: &RenderFile, spp: u32) -> Result<Option<Adaptive>, SceneError> {
    let Some(threshold) = &r.noise_threshold else {
        if let Some(m) = &r.min_spp {
            return Err(t.err(
                m.span(),
                "render.min_spp",
                "is the first round of adaptive sampling: set render.noise_threshold too",
            ));
        }
        return Ok(None);
    };
    let th = *threshold.get_ref();
    if !Adaptive::threshold_ok(th) {
        return Err(t.err(
            threshold.span(),
            "render.noise_threshold",
            "must be a number at least 0 (0: every pixel takes every sample)",
        ));
    }
    let min_spp = match &r.min_spp {
        Some(m) => {
            let v = *m.get_ref();
            if !Adaptive::min_spp_ok(v, spp) {
                return Err(t.err(
                    m.span(),
                    "render.min_spp",
                    format!("must be between 2 and render.spp ({spp})"),
                ));
            }
            v
        }
        None => Adaptive::default_min_spp(spp),
    };
    Ok(Some(Adaptive {
        threshold: th,
        min_spp,
    }))
}

fn outputs(t: &Text, raw: Option<&OutputsFile>) -> Result<ViewsOutputs, SceneError> {
    let mut out = ViewsOutputs {
        png: true,
        exr: false,
        aovs: AovSet::NONE,
        camera_normals: false,
    };
    let Some(o) = raw else {
        return Ok(out);
    };
    if let Some(c) = &o.color {
        out.png = false;
        for name in c.get_ref() {
            match name.as_str() {
                "png" => out.png = true,
                "exr" => out.exr = true,
                other => {
                    return Err(t.err(
                        c.span(),
                        "outputs.color",
                        format!("unknown colour format {other:?} (known: png, exr)"),
                    ));
                }
            }
        }
        if !(out.png || out.exr) {
            return Err(t.err(c.span(), "outputs.color", "name png, exr or both"));
        }
    }
    if let Some(a) = &o.aov {
        out.aovs = AovSet::from_names(a.get_ref().iter().map(String::as_str))
            .map_err(|e| t.err(a.span(), "outputs.aov", e))?;
    }
    if let Some(n) = &o.normals {
        out.camera_normals = match n.get_ref().as_str() {
            "world" => false,
            "camera" => true,
            other => {
                return Err(t.err(
                    n.span(),
                    "outputs.normals",
                    format!("{other:?}: world or camera"),
                ));
            }
        };
    }
    Ok(out)
}

/// Read a JSON camera file: `frames`, each with a 4×4 camera-to-world
/// `transform_matrix` (NeRF's axes) and, there or at the top level,
/// `camera_angle_x` (radians) or `fl_x` with `w` (pixels), and optionally
/// `fl_y`, `cx` and `cy` (NeRF's: `cx = w/2` is centred). Errors name the
/// JSON path.
pub fn read_cameras(path: &Path) -> Result<Vec<ExplicitCamera>, SceneError> {
    let file = path.display().to_string();
    let at = |p: &str| super::builder::Origin::path(&file, p);
    let text = std::fs::read_to_string(path)
        .map_err(|e| at("").error(format!("cannot read the camera file: {e}")))?;
    let json: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| at("").error(format!("line {}: not JSON: {e}", e.line())))?;
    let frames = json
        .get("frames")
        .and_then(|f| f.as_array())
        .ok_or_else(|| {
            at("frames").error("missing: an array of frames, each with a transform_matrix")
        })?;
    if frames.is_empty() {
        return Err(at("frames").error("no cameras"));
    }
    let top = intrinsics(&json, "", &at)?;
    let mut out = Vec::with_capacity(frames.len());
    for (i, f) in frames.iter().enumerate() {
        let here = format!("frames[{i}]");
        let intrinsics = intrinsics(f, &format!("{here}."), &at)?.or(top).ok_or_else(|| {
            at(&here).error("no field of view: give camera_angle_x (radians) or fl_x and w, here or at the top level")
        })?;
        let m = f
            .get("transform_matrix")
            .ok_or_else(|| at(&format!("{here}.transform_matrix")).error("missing"))?;
        let matrix =
            rigid_matrix(m).map_err(|e| at(&format!("{here}.transform_matrix")).error(e))?;
        out.push(ExplicitCamera {
            camera_to_world: matrix,
            intrinsics,
        });
    }
    Ok(out)
}

/// The intrinsics object `v` gives, checking them: `camera_angle_x`, or
/// `fl_x` with `w` (pixels); `fl_y` (with `fl_x`), `cx` (with `w`) and `cy`
/// (with `h`) where given. `cx`, `cy` are NeRF's: continuous pixel
/// coordinates, `(w/2, h/2)` for a centred principal point.
fn intrinsics(
    v: &serde_json::Value,
    prefix: &str,
    at: &dyn Fn(&str) -> super::builder::Origin,
) -> Result<Option<Intrinsics>, SceneError> {
    let num = |k: &str| -> Result<Option<f64>, SceneError> {
        match v.get(k) {
            None => Ok(None),
            Some(x) => match x.as_f64() {
                Some(x) if x.is_finite() => Ok(Some(x)),
                _ => Err(at(&format!("{prefix}{k}")).error("must be a finite number")),
            },
        }
    };
    let (w, h) = (num("w")?, num("h")?);
    for (key, size) in [("w", w), ("h", h)] {
        if size.is_some_and(|s| s <= 0.0) {
            return Err(at(&format!("{prefix}{key}")).error("must be positive (pixels)"));
        }
    }
    let (fx, fy) = (num("fl_x")?, num("fl_y")?);
    let angle = match (num("camera_angle_x")?, fx) {
        (Some(a), _) => Some((a, "camera_angle_x")),
        (None, Some(fx)) => match w {
            Some(w) if fx > 0.0 => Some((2.0 * (w / (2.0 * fx)).atan(), "fl_x")),
            _ => {
                return Err(
                    at(&format!("{prefix}fl_x")).error("needs a positive fl_x and w (pixels)")
                );
            }
        },
        (None, None) => None,
    };
    let angle_x = match angle {
        Some((a, _)) if a > 0.0 && a < std::f64::consts::PI => a,
        Some((a, key)) => {
            return Err(at(&format!("{prefix}{key}")).error(format!(
                "a field of view of {a} radians: must be between 0 and pi"
            )));
        }
        None => return Ok(None),
    };
    let aspect = match (fx, fy) {
        (Some(fx), Some(fy)) if fy > 0.0 && fx > 0.0 => fy / fx,
        (_, Some(fy)) => {
            return Err(at(&format!("{prefix}fl_y")).error(format!(
                "{fy}: needs a positive fl_y beside a positive fl_x"
            )));
        }
        _ => 1.0,
    };
    let mut offset = [0.0f32; 2];
    for (i, (key, size)) in [("cx", w), ("cy", h)].into_iter().enumerate() {
        match (num(key)?, size) {
            (Some(c), Some(size)) => offset[i] = (c / size - 0.5) as f32,
            (Some(_), None) => {
                return Err(at(&format!("{prefix}{key}")).error(format!(
                    "needs the image's size {} (pixels) beside it",
                    ["w", "h"][i]
                )));
            }
            _ => {}
        }
    }
    Ok(Some(Intrinsics {
        angle_x: angle_x as f32,
        focal_aspect_y: aspect as f32,
        principal_offset: offset,
    }))
}

/// A 4×4 rigid transform (rows): a rotation and a translation, last row
/// `0 0 0 1`.
fn rigid_matrix(v: &serde_json::Value) -> Result<[[f32; 4]; 4], String> {
    let bad = || "must be 4 rows of 4 finite numbers".to_string();
    let rows = v.as_array().filter(|r| r.len() == 4).ok_or_else(bad)?;
    let mut m = [[0.0f32; 4]; 4];
    for (i, row) in rows.iter().enumerate() {
        let row = row.as_array().filter(|r| r.len() == 4).ok_or_else(bad)?;
        for (j, x) in row.iter().enumerate() {
            m[i][j] = x.as_f64().filter(|x| x.is_finite()).ok_or_else(bad)? as f32;
        }
    }
    if (0..4).any(|j| (m[3][j] - [0.0, 0.0, 0.0, 1.0][j]).abs() > 1e-5) {
        return Err("its last row must be 0 0 0 1".into());
    }
    let col = |j: usize| Vec3::new(m[0][j], m[1][j], m[2][j]);
    let (x, y, z) = (col(0), col(1), col(2));
    let orthonormal = [x.length(), y.length(), z.length()]
        .iter()
        .all(|l| (l - 1.0).abs() < 1e-3)
        && [x.dot(y), y.dot(z), z.dot(x)]
            .iter()
            .all(|d| d.abs() < 1e-3);
    if !orthonormal || x.cross(y).dot(z) < 0.0 {
        return Err("its upper 3x3 must be a rotation (orthonormal columns, determinant 1): no scale, shear or mirror".into());
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wildcards() {
        assert!(wildcard_match(b"*.glb", b"a.glb"));
        assert!(wildcard_match(b"a?c*", b"abcdef"));
        assert!(!wildcard_match(b"*.glb", b"a.gltf"));
        assert!(wildcard_match(b"*", b""));
    }

    #[test]
    fn errors_name_line_and_field() {
        let e = ViewsJob::parse(
            "[assets]\nfiles = [\"a.glb\"]\n[cameras]\nkind = \"orbit\"\nviews = 0\n",
            "j.toml",
        )
        .unwrap_err();
        assert_eq!(
            (e.line, e.field.as_deref()),
            (5, Some("cameras.views")),
            "{e}"
        );
        let e = ViewsJob::parse(
            "[assets]\nfiles = [\"a.glb\"]\n[render]\nspp = 4\nsamples = 3\n",
            "j.toml",
        )
        .unwrap_err();
        assert_eq!(e.line, 5, "{e}");
        assert!(e.to_string().contains("samples"), "{e}");
    }
}
