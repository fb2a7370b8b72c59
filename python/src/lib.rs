//! `wavetrace._wavetrace`: the native module of the `wavetrace` Python
//! package. It opens scenes, makes cameras and renders into buffers that
//! NumPy views without a copy (`__array_interface__`); the Python side
//! (`python/wavetrace/__init__.py`) turns them into arrays.
//!
//! A render releases the GIL; the calling thread waits for it, checking
//! for signals (Ctrl-C becomes `KeyboardInterrupt`, the render stops
//! between tiles) and reporting progress between sample passes.

mod views;

use glam::Vec3;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Mutex, mpsc};
use std::time::Duration;
use wavetrace::film::Film;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::aov::Sum;
use wavetrace::scene::camera::Camera as CoreCamera;
use wavetrace::scene::environment::{EnvSource, overridden};
use wavetrace::scene::options::{Integrator, SamplerKind};
use wavetrace::scene::{Aov, AovSet};

create_exception!(
    _wavetrace,
    WavetraceError,
    PyException,
    "A scene, setting or file wavetrace refuses; the message is the command line's."
);

fn error(e: wavetrace::Error) -> PyErr {
    WavetraceError::new_err(e.to_string())
}

fn settings_error(message: String) -> PyErr {
    WavetraceError::new_err(format!("invalid setting: {message}"))
}

/// A pinhole camera: a position, a viewing direction, an up direction and
/// either a vertical field of view (at any image size) or OpenCV
/// intrinsics (for the size they were given at, scaled with the height at
/// other sizes). The conventions are the core camera's
/// (`wavetrace::scene::camera::Camera`), shared with `wavetrace views`.
#[pyclass(frozen, module = "wavetrace._wavetrace")]
#[derive(Clone)]
struct Camera {
    /// The frame, and the intrinsics where `fov_y` is `None`.
    core: CoreCamera,
    /// The vertical field of view in degrees, kept at every image size.
    fov_y: Option<f32>,
}

fn vec3(v: [f64; 3], what: &str) -> PyResult<Vec3> {
    let v = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PyValueError::new_err(format!("{what} is not finite: {v}")))
    }
}

fn check_fov(fov_y: f64) -> PyResult<f32> {
    if fov_y.is_finite() && fov_y > 0.0 && fov_y < 180.0 {
        Ok(fov_y as f32)
    } else {
        Err(PyValueError::new_err(format!(
            "fov_y is a vertical field of view in degrees, between 0 and 180 (exclusive): got {fov_y}"
        )))
    }
}

/// The core camera's frame (`right = forward × up`, made orthonormal).
fn frame(
    position: Vec3,
    forward: Vec3,
    up: Vec3,
    focal: f32,
    size: (u32, u32),
) -> PyResult<CoreCamera> {
    CoreCamera::new(position, forward, up, focal, size.0, size.1).ok_or_else(|| {
        PyValueError::new_err(format!(
            "a camera needs a viewing direction and an up direction that are not parallel: forward {forward}, up {up}"
        ))
    })
}

impl Camera {
    fn with_fov(position: Vec3, forward: Vec3, up: Vec3, fov_y: f32) -> PyResult<Self> {
        Ok(Self {
            core: frame(position, forward, up, 1.0, (1, 1))?,
            fov_y: Some(fov_y),
        })
    }

    fn from_core(c: &CoreCamera) -> Self {
        Self {
            core: c.clone(),
            fov_y: None,
        }
    }

    /// The camera to hand the renderer for a `width × height` render (it
    /// scales a camera of another size itself, as the command line does).
    fn core(&self, width: u32, height: u32) -> CoreCamera {
        match self.fov_y {
            Some(fov) => CoreCamera {
                focal_length_px: CoreCamera::focal_from_vfov(fov, height),
                width,
                height,
                ..self.core.clone()
            },
            None => self.core.clone(),
        }
    }

    /// The camera at exactly `width × height`.
    fn sized(&self, width: u32, height: u32) -> CoreCamera {
        self.core(width, height).resized(width, height)
    }
}

fn orthonormal(axes: [Vec3; 3]) -> bool {
    let unit = axes.iter().all(|a| (a.length() - 1.0).abs() < 1e-4);
    let orthogonal = axes[0].dot(axes[1]).abs() < 1e-4
        && axes[1].dot(axes[2]).abs() < 1e-4
        && axes[0].dot(axes[2]).abs() < 1e-4;
    unit && orthogonal
}

#[pymethods]
impl Camera {
    /// A camera at `eye` looking at `target`, `up` pointing up in the image.
    #[staticmethod]
    #[pyo3(signature = (eye, target, up = [0.0, 1.0, 0.0], fov_y = 40.0))]
    fn look_at(eye: [f64; 3], target: [f64; 3], up: [f64; 3], fov_y: f64) -> PyResult<Self> {
        let eye = vec3(eye, "eye")?;
        let target = vec3(target, "target")?;
        Self::with_fov(eye, target - eye, vec3(up, "up")?, check_fov(fov_y)?)
    }

    /// A camera from a 4×4 camera-to-world matrix in the OpenGL (NeRF,
    /// Blender) convention: its columns are the camera's right (+X), up
    /// (+Y) and backward (+Z; the camera looks down −Z) axes and its
    /// position. The rotation must be orthonormal (no scale, no shear).
    #[staticmethod]
    #[pyo3(signature = (matrix, fov_y = 40.0))]
    fn from_matrix(matrix: [[f64; 4]; 4], fov_y: f64) -> PyResult<Self> {
        let col = |j: usize| vec3([matrix[0][j], matrix[1][j], matrix[2][j]], "the matrix");
        let (right, up, back, position) = (col(0)?, col(1)?, col(2)?, col(3)?);
        if matrix[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(PyValueError::new_err(format!(
                "a camera-to-world matrix's last row is [0, 0, 0, 1]: got {:?}",
                matrix[3]
            )));
        }
        if !orthonormal([right, up, back]) || right.cross(up).dot(back) < 0.0 {
            return Err(PyValueError::new_err(
                "a camera-to-world matrix's rotation must be orthonormal and right-handed (columns right, up, backward)",
            ));
        }
        Self::with_fov(position, -back, up, check_fov(fov_y)?)
    }

    /// A camera from OpenCV's intrinsics `K` (3×3) and extrinsics `R`
    /// (3×3), `t` (3): a world point `X` is at `R X + t` in the camera's
    /// frame (x right, y down, z forward) and at pixel `K (R X + t)` after
    /// the division by z, with integer pixel coordinates at pixel centres,
    /// for an image of `width` × `height` pixels. Any positive `fx`, `fy`
    /// and any principal point; no skew.
    #[staticmethod]
    #[pyo3(name = "from_opencv")]
    fn from_opencv(
        k: [[f64; 3]; 3],
        r: [[f64; 3]; 3],
        t: [f64; 3],
        width: u32,
        height: u32,
    ) -> PyResult<Self> {
        let (fx, fy, cx, cy) = (k[0][0], k[1][1], k[0][2], k[1][2]);
        if width == 0 || height == 0 {
            return Err(PyValueError::new_err(format!(
                "the image size must be positive: got {width}×{height}"
            )));
        }
        if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "K needs positive, finite focal lengths: got fx = {fx}, fy = {fy}"
            )));
        }
        if !(cx.is_finite() && cy.is_finite())
            || k[0][1] != 0.0
            || k[1][0] != 0.0
            || k[2] != [0.0, 0.0, 1.0]
        {
            return Err(PyValueError::new_err(format!(
                "K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with a finite principal point (wavetrace's pixels have no skew): got {k:?}"
            )));
        }
        let row = |i: usize| vec3(r[i], "R");
        let (x, y, z) = (row(0)?, row(1)?, row(2)?);
        if !orthonormal([x, y, z]) || x.cross(y).dot(z) < 0.0 {
            return Err(PyValueError::new_err(
                "R must be a rotation (orthonormal, determinant 1)",
            ));
        }
        let t = vec3(t, "t")?;
        // X = Rᵀ (x_cam − t): the camera's centre is at −Rᵀ t.
        let position = -(x * t.x + y * t.y + z * t.z);
        let core = frame(position, z, -y, fy as f32, (width, height))?
            .with_intrinsics(fx as f32, fy as f32, cx as f32, cy as f32)
            .ok_or_else(|| PyValueError::new_err(format!("K is out of range: {k:?}")))?;
        Ok(Self { core, fov_y: None })
    }

    /// The camera's position in world space.
    #[getter]
    fn position(&self) -> [f32; 3] {
        self.core.position.to_array()
    }

    /// The unit viewing direction.
    #[getter]
    fn forward(&self) -> [f32; 3] {
        self.core.forward.to_array()
    }

    /// The unit up direction of the image (orthogonal to `forward`).
    #[getter]
    fn up(&self) -> [f32; 3] {
        self.core.up.to_array()
    }

    /// The vertical field of view in degrees (of a centred image).
    #[getter]
    fn fov_y(&self) -> f32 {
        self.fov_y.unwrap_or_else(|| {
            let c = &self.core;
            2.0 * (0.5 * c.height as f32 / c.focal_length_px)
                .atan()
                .to_degrees()
        })
    }

    /// The 4×4 camera-to-world matrix, OpenGL convention (as
    /// `from_matrix` takes it).
    fn matrix(&self) -> [[f64; 4]; 4] {
        self.core.camera_to_world().map(|row| row.map(f64::from))
    }

    /// OpenCV's intrinsics `K` for an image of `width` × `height` pixels.
    fn intrinsics(&self, width: u32, height: u32) -> [[f64; 3]; 3] {
        let k = self.sized(width, height).opencv_k();
        k.map(|row| row.map(f64::from))
    }

    /// OpenCV's extrinsics `(R, t)` (world to camera: x right, y down,
    /// z forward).
    fn extrinsics(&self) -> ([[f64; 3]; 3], [f64; 3]) {
        let (r, t) = self.core.opencv_rt();
        (r.map(|row| row.map(f64::from)), t.map(f64::from))
    }

    /// Where the world point `point` is seen in an image of `width` ×
    /// `height` pixels: `(x, y)` in continuous pixel coordinates (pixel
    /// `(i, j)` covers `[i, i + 1) × [j, j + 1)`, row 0 at the top), or
    /// `None` behind the camera.
    fn project(&self, point: [f64; 3], width: u32, height: u32) -> Option<(f64, f64)> {
        let p = vec3(point, "point").ok()?;
        self.sized(width, height).project(p).map(|[x, y]| (x, y))
    }

    fn __repr__(&self) -> String {
        format!(
            "Camera(position={:?}, forward={:?}, up={:?}, fov_y={})",
            self.position(),
            self.forward(),
            self.up(),
            self.fov_y()
        )
    }
}

/// Pixels NumPy reads without a copy through `__array_interface__`.
#[pyclass(frozen, module = "wavetrace._wavetrace")]
struct Buffer {
    data: Data,
    shape: Vec<usize>,
}

enum Data {
    F32(Vec<f32>),
    U32(Vec<u32>),
}

#[pymethods]
impl Buffer {
    #[getter]
    fn __array_interface__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let (pointer, typestr) = match &self.data {
            Data::F32(v) => (v.as_ptr() as usize, "<f4"),
            Data::U32(v) => (v.as_ptr() as usize, "<u4"),
        };
        d.set_item("shape", pyo3::types::PyTuple::new(py, &self.shape)?)?;
        d.set_item("typestr", typestr)?;
        // Read-only: the buffer is shared by every array made from it.
        d.set_item("data", (pointer, true))?;
        d.set_item("version", 3)?;
        Ok(d)
    }
}

/// The settings that need a renderer of their own (a change of camera or
/// seed does not).
#[derive(Clone, PartialEq)]
struct Key {
    width: u32,
    height: u32,
    max_depth: u32,
    threads: usize,
    engine: &'static str,
    integrator: &'static str,
    sampler: &'static str,
    aovs: Vec<&'static str>,
    env: Option<(String, Option<u32>, Option<u32>)>,
    transparent: bool,
}

struct State {
    /// The scene as loaded (its own environment).
    scene: wavetrace::scene::Scene,
    /// The renderer of the last render, kept for the next one.
    cached: Option<(Key, Renderer)>,
}

/// A scene opened from a file: TOML, glTF/GLB, PLY (an OBJ mesh is placed
/// in a TOML scene).
#[pyclass(frozen, module = "wavetrace._wavetrace")]
struct Scene {
    name: String,
    /// The scene's own camera, as the command line renders it.
    own_camera: CoreCamera,
    camera: Camera,
    resolution: (u32, u32),
    bounds: ([f32; 3], [f32; 3]),
    triangles: usize,
    spheres: usize,
    sources: Vec<PathBuf>,
    warnings: Vec<String>,
    objects: Vec<(u32, String)>,
    state: Mutex<State>,
}

/// One render's request, checked, before the GIL is released.
struct Request {
    key: Key,
    settings: RenderSettings,
    camera: CoreCamera,
    env: Option<EnvSource>,
    env_strength: Option<f32>,
    env_rotation: Option<f32>,
    transparent: bool,
    passes: Vec<Range<u32>>,
}

/// At most this many passes per render (progress and Ctrl-C act between
/// them and between tiles).
const MAX_PASSES: u32 = 32;

fn passes(spp: u32) -> Vec<Range<u32>> {
    let step = spp.div_ceil(MAX_PASSES).max(1);
    (0..spp.div_ceil(step))
        .map(|i| i * step..((i + 1) * step).min(spp))
        .collect()
}

fn named<T: Copy>(
    name: Option<&str>,
    what: &str,
    known: &[&str],
    from: impl Fn(&str) -> Option<T>,
    default: T,
) -> PyResult<T> {
    match name {
        None => Ok(default),
        Some(n) => from(n).ok_or_else(|| {
            settings_error(format!(
                "unknown {what} {n:?} (known: {})",
                known.join(", ")
            ))
        }),
    }
}

impl Scene {
    fn wrap(scene: wavetrace::scene::Scene, warnings: Vec<String>) -> Self {
        let (lo, hi) = scene.bounds();
        Self {
            name: scene.name.clone(),
            own_camera: scene.camera.clone(),
            camera: Camera::from_core(&scene.camera),
            resolution: (scene.camera.width, scene.camera.height),
            bounds: (lo.to_array(), hi.to_array()),
            triangles: scene.triangles.len(),
            spheres: scene.spheres.len(),
            sources: scene.sources.clone(),
            warnings,
            objects: (scene.objects.legend())
                .map(|(id, name)| (id, name.to_string()))
                .collect(),
            state: Mutex::new(State {
                scene,
                cached: None,
            }),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn request(
        &self,
        camera: Option<&Camera>,
        spp: u32,
        seed: u64,
        width: Option<u32>,
        height: Option<u32>,
        integrator: Option<&str>,
        sampler: Option<&str>,
        max_depth: Option<u32>,
        engine: Option<&str>,
        env: Option<&str>,
        env_strength: Option<f32>,
        env_rotation: Option<f32>,
        aovs: &[String],
        transparent: bool,
        threads: Option<usize>,
    ) -> PyResult<Request> {
        let state = self
            .state
            .lock()
            .expect("no render panics while holding the scene");
        let mut s = RenderSettings::for_scene(&state.scene);
        drop(state);
        s.width = width.unwrap_or(self.resolution.0);
        s.height = height.unwrap_or(self.resolution.1);
        s.spp = spp;
        s.seed = seed;
        s.max_depth = max_depth.unwrap_or(s.max_depth);
        s.threads = threads.unwrap_or(s.threads);
        s.integrator = named(
            integrator,
            "integrator",
            Integrator::NAMES,
            Integrator::from_name,
            s.integrator,
        )?;
        s.sampler = named(
            sampler,
            "sampler",
            SamplerKind::NAMES,
            SamplerKind::from_name,
            s.sampler,
        )?;
        s.engine = match engine {
            None => s.engine,
            Some(n) => Engine::from_name(n).map_err(error)?,
        };
        // Alpha always: the colour's fourth channel (it changes no bit of
        // the colour, and costs a count per pixel).
        s.aovs = AovSet::from_names(aovs.iter().map(String::as_str))
            .map_err(|e| settings_error(format!("aovs: {e}")))?
            .with(Aov::Alpha);
        s.validate().map_err(error)?;
        let key = Key {
            width: s.width,
            height: s.height,
            max_depth: s.max_depth,
            threads: s.threads,
            engine: s.engine.name(),
            integrator: s.integrator.name(),
            sampler: s.sampler.name(),
            aovs: s.aovs.names(),
            env: (env.is_some() || env_strength.is_some() || env_rotation.is_some()).then(|| {
                (
                    env.unwrap_or("").to_string(),
                    env_strength.map(f32::to_bits),
                    env_rotation.map(f32::to_bits),
                )
            }),
            transparent,
        };
        let camera = match camera {
            Some(c) => c.core(s.width, s.height),
            None => self.own_camera.clone(),
        };
        Ok(Request {
            key,
            camera,
            env: env.map(EnvSource::parse),
            env_strength,
            env_rotation,
            transparent,
            passes: passes(spp),
            settings: s,
        })
    }
}

/// The renderer for `request`, made anew only when a setting other than
/// the camera and seed changed.
fn prepare<'a>(state: &'a mut State, request: &Request) -> wavetrace::Result<&'a mut Renderer> {
    if state
        .cached
        .as_ref()
        .is_none_or(|(key, _)| *key != request.key)
    {
        state.cached = None;
        let renderer = if request.key.env.is_some() || request.transparent {
            let mut scene = state.scene.clone();
            let env = overridden(
                scene.environment.as_ref(),
                request.env.as_ref(),
                request.env_strength,
                request.env_rotation,
            )
            .map_err(wavetrace::Error::Settings)?;
            if let Some(env) = env {
                scene.set_environment(env);
            }
            if request.transparent {
                scene.make_transparent();
            }
            Renderer::new(&scene, &request.settings)?
        } else {
            Renderer::new(&state.scene, &request.settings)?
        };
        state.cached = Some((request.key.clone(), renderer));
    }
    let (_, renderer) = state.cached.as_mut().expect("set above");
    renderer.set_view(&request.camera, request.settings.seed);
    Ok(renderer)
}

/// What the waiting thread hears from the rendering one.
enum Event {
    Pass,
    Done(Box<Option<wavetrace::Result<Film>>>),
}

/// Render `request`'s passes on a thread of their own while this one
/// (with the GIL released) waits, checks for signals and reports
/// progress. `None`: stopped by a signal or by the progress callback's
/// exception, which is returned.
fn render_waiting(
    py: Python<'_>,
    scene: &Scene,
    request: &Request,
    progress: Option<&Bound<'_, PyAny>>,
) -> PyResult<Film> {
    let stop = AtomicBool::new(false);
    let done = AtomicU32::new(0);
    let progress: Option<Py<PyAny>> = progress.map(|p| p.clone().unbind());
    let work = |tx: mpsc::Sender<Event>| {
        let mut state = scene
            .state
            .lock()
            .expect("no render panics while holding the scene");
        let result = prepare(&mut state, request).map(|renderer| {
            let mut film = renderer.new_film();
            for pass in &request.passes {
                renderer.render_samples_or_stop(pass.clone(), &mut film, &|| {
                    stop.load(Ordering::Relaxed)
                })?;
                done.store(pass.end, Ordering::Relaxed);
                let _ = tx.send(Event::Pass);
            }
            Some(film)
        });
        let _ = tx.send(Event::Done(Box::new(result.transpose())));
    };
    let wait = |rx: mpsc::Receiver<Event>| -> PyResult<Option<wavetrace::Result<Film>>> {
        let mut reported = 0;
        loop {
            let event = rx.recv_timeout(Duration::from_millis(50));
            let finished = match event {
                Ok(Event::Done(result)) => Some(*result),
                Err(mpsc::RecvTimeoutError::Disconnected) => Some(None),
                _ => None,
            };
            if let Some(result) = finished {
                return Ok(result);
            }
            let checked = Python::attach(|py| -> PyResult<()> {
                py.check_signals()?;
                let now = done.load(Ordering::Relaxed);
                if let Some(callback) = &progress
                    && now > reported
                {
                    report(callback.bind(py), reported, now, request.settings.spp)?;
                    reported = now;
                }
                Ok(())
            });
            if let Err(e) = checked {
                stop.store(true, Ordering::Relaxed);
                // The rendering thread ends at its next tile.
                while !matches!(rx.recv(), Ok(Event::Done(_)) | Err(_)) {}
                return Err(e);
            }
        }
    };
    let run = || {
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel();
            s.spawn(move || work(tx));
            wait(rx)
        })
    };
    let outcome = py.detach(run)?;
    match outcome {
        Some(Ok(film)) => Ok(film),
        Some(Err(e)) => Err(error(e)),
        None => Err(WavetraceError::new_err("the render was stopped")),
    }
}

/// Tell the caller's progress object that samples `before..now` of
/// `total` are done: a tqdm-like object's `update(n)`, or a callable's
/// `(done, total)`.
fn report(callback: &Bound<'_, PyAny>, before: u32, now: u32, total: u32) -> PyResult<()> {
    if callback.hasattr("update")? && !callback.is_callable() {
        callback.call_method1("update", (now - before,))?;
    } else {
        callback.call1((now, total))?;
    }
    Ok(())
}

/// The colour and its alpha (the fraction of the pixel's camera rays that
/// hit something), and the other AOVs, as the arrays' buffers.
fn buffers(film: &Film) -> Vec<(&'static str, Buffer)> {
    let size = (film.width as usize, film.height as usize);
    buffers_of(size, film.to_rgb(), film.aov_images())
}

/// The arrays' buffers of a `(width, height)` image: the colour `rgb` with
/// the `Alpha` AOV's as its fourth channel (1 without), and the other AOVs.
fn buffers_of(
    (w, h): (usize, usize),
    rgb: Vec<[f32; 3]>,
    mut aovs: Vec<(Aov, Vec<[f32; 3]>)>,
) -> Vec<(&'static str, Buffer)> {
    let shape = |channels: usize| match channels {
        1 => vec![h, w],
        c => vec![h, w, c],
    };
    let alpha = aovs
        .iter()
        .position(|(aov, _)| *aov == Aov::Alpha)
        .map(|k| aovs.remove(k).1);
    let mut rgba = Vec::with_capacity(rgb.len() * 4);
    for (i, p) in rgb.into_iter().enumerate() {
        let a = alpha.as_ref().map_or(1.0, |alpha| alpha[i][0]);
        rgba.extend_from_slice(&[p[0], p[1], p[2], a]);
    }
    let mut out = vec![(
        "color",
        Buffer {
            data: Data::F32(rgba),
            shape: shape(4),
        },
    )];
    for (aov, pixels) in aovs {
        let (data, channels) = match (aov.def().sum, aov.def().layer.1.len()) {
            // Exact: the film holds ids below 2²⁴.
            (Sum::Votes, _) => (Data::U32(pixels.iter().map(|p| p[0] as u32).collect()), 1),
            (_, 1) => (Data::F32(pixels.iter().map(|p| p[0]).collect()), 1),
            _ => (Data::F32(pixels.into_iter().flatten().collect()), 3),
        };
        out.push((
            aov.name(),
            Buffer {
                data,
                shape: shape(channels),
            },
        ));
    }
    out
}

#[pymethods]
impl Scene {
    /// The scene's name (its file's stem).
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The scene's own camera (the file's, or the default framing).
    #[getter]
    fn camera(&self) -> Camera {
        self.camera.clone()
    }

    /// The scene's own image size `(width, height)`.
    #[getter]
    fn resolution(&self) -> (u32, u32) {
        self.resolution
    }

    /// The corners `(min, max)` of the box around the scene's geometry.
    #[getter]
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        self.bounds
    }

    /// How many triangles the scene holds (instances counted each time).
    #[getter]
    fn triangles(&self) -> usize {
        self.triangles
    }

    /// How many spheres the scene holds.
    #[getter]
    fn spheres(&self) -> usize {
        self.spheres
    }

    /// The files the scene was read from.
    #[getter]
    fn sources(&self) -> Vec<PathBuf> {
        self.sources.clone()
    }

    /// What the loader had to say (ignored extensions, skipped lines…).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// The object-id legend: `(id, name)` for every object (ids from 1;
    /// 0 is the background in `object_id` images).
    #[getter]
    fn objects(&self) -> Vec<(u32, String)> {
        self.objects.clone()
    }

    /// Render and return `{name: Buffer}` for the Python side to view as
    /// arrays. See `wavetrace.Scene.render` for the arguments.
    #[pyo3(signature = (camera = None, spp = 16, seed = 0, width = None, height = None, integrator = None, sampler = None, max_depth = None, engine = None, env = None, env_strength = None, env_rotation = None, aovs = Vec::new(), transparent = false, threads = None, progress = None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        camera: Option<PyRef<'py, Camera>>,
        spp: u32,
        seed: u64,
        width: Option<u32>,
        height: Option<u32>,
        integrator: Option<&str>,
        sampler: Option<&str>,
        max_depth: Option<u32>,
        engine: Option<&str>,
        env: Option<&str>,
        env_strength: Option<f32>,
        env_rotation: Option<f32>,
        aovs: Vec<String>,
        transparent: bool,
        threads: Option<usize>,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let request = self.request(
            camera.as_deref(),
            spp,
            seed,
            width,
            height,
            integrator,
            sampler,
            max_depth,
            engine,
            env,
            env_strength,
            env_rotation,
            &aovs,
            transparent,
            threads,
        )?;
        let film = render_waiting(py, self, &request, progress.as_ref())?;
        let out = PyDict::new(py);
        for (name, buffer) in py.detach(|| buffers(&film)) {
            out.set_item(name, buffer)?;
        }
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene(name={:?}, triangles={}, spheres={}, resolution={:?})",
            self.name, self.triangles, self.spheres, self.resolution
        )
    }
}

/// Open a scene file: TOML, glTF/GLB or PLY (`camera`: one of a glTF
/// file's cameras, by name or index).
#[pyfunction]
#[pyo3(signature = (path, camera = None))]
fn load(py: Python<'_>, path: PathBuf, camera: Option<String>) -> PyResult<Scene> {
    let (scene, warnings) = py
        .detach(|| wavetrace::render::open_scene(&path, camera.as_deref()))
        .map_err(error)?;
    Ok(Scene::wrap(scene, warnings))
}

/// The built-in Cornell box (the default scene of `wavetrace`).
#[pyfunction]
fn cornell() -> Scene {
    Scene::wrap(wavetrace::scene::Scene::cornell(), Vec::new())
}

#[pymodule]
fn _wavetrace(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(cornell, m)?)?;
    m.add_function(wrap_pyfunction!(views::views, m)?)?;
    m.add_class::<views::Views>()?;
    m.add_class::<Scene>()?;
    m.add_class::<Camera>()?;
    m.add_class::<Buffer>()?;
    m.add("WavetraceError", m.py().get_type::<WavetraceError>())?;
    Ok(())
}
