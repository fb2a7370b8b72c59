//! Plumbing shared by the integration tests: fresh temp directories, running
//! the `wavetrace` binary as a user (or a farm) would, and small settings.
//!
//! Each test file that says `mod common;` compiles its own copy of this
//! module and uses only part of it, hence the `allow(dead_code)`.

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::ffi::OsStr;
use std::fmt::Debug;
use std::io::Read;
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use wavetrace::film::Film;
use wavetrace::render::RenderSettings;
use wavetrace::scene::Scene;

/// The `wavetrace` binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_wavetrace");

/// How long a run of the binary may take before a test gives up on it.
pub const PATIENCE: Duration = Duration::from_secs(120);

/// The environment variables through which a scheduler (Slurm, a Kubernetes
/// Indexed Job) picks the shard and the threads. Every run of the binary has
/// them removed, so the tests do not depend on where they run; a test that
/// is about them sets them with [`run_env`].
pub const SCHEDULER_VARS: [&str; 7] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_MAX",
    "SLURM_ARRAY_TASK_STEP",
    "SLURM_CPUS_PER_TASK",
    "JOB_COMPLETION_INDEX",
];

// --- Temp directories ---

/// A fresh, empty directory for one test, removed (with what is in it) when
/// dropped. It derefs to its [`Path`], so `dir.join("x.png")` and `&dir`
/// where a `&Path` is wanted both work.
pub struct TempDir(PathBuf);

impl TempDir {
    /// A new directory named after the test file, `name`, the process and a
    /// counter, so no two tests (nor two runs at once) share one. It lies
    /// under Cargo's `CARGO_TARGET_TMPDIR` (`target/tmp`), or the system's
    /// temp dir where that is not set.
    pub fn new(name: &str) -> Self {
        static COUNT: AtomicUsize = AtomicUsize::new(0);
        let root = option_env!("CARGO_TARGET_TMPDIR")
            .map(PathBuf::from)
            .unwrap_or_else(std::env::temp_dir);
        let dir = root.join(format!(
            "wavetrace-{}-{name}-{}-{}",
            env!("CARGO_CRATE_NAME"),
            std::process::id(),
            COUNT.fetch_add(1, Ordering::Relaxed)
        ));
        // Left over by an earlier process of the same id.
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.0
    }

    /// The names of the entries in the directory, sorted.
    pub fn files(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A path as the `&str` a command line takes.
pub fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

// --- Running the binary ---

/// `wavetrace ARGS`, ready to run in `dir`: the [`SCHEDULER_VARS`] removed,
/// stdin null, stdout and stderr captured.
pub fn wavetrace<S: AsRef<OsStr>>(dir: &Path, args: &[S]) -> Command {
    let mut cmd = Command::new(BIN);
    cmd.current_dir(dir)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for var in SCHEDULER_VARS {
        cmd.env_remove(var);
    }
    cmd
}

/// Runs `cmd` to the end and returns its output; if it is still running
/// after `limit`, kills it and panics with what it printed.
pub fn finish(cmd: &mut Command, limit: Duration) -> Output {
    let mut child = cmd.spawn().unwrap();
    // Read the pipes while waiting, so a chatty run cannot fill one and
    // stall until the limit.
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                pipe.read_to_end(&mut bytes).unwrap();
            }
            bytes
        })
    };
    let stdout = drain(child.stdout.take().map(|p| Box::new(p) as _));
    let stderr = drain(child.stderr.take().map(|p| Box::new(p) as _));
    let status = wait_within(&mut child, limit);
    let output = Output {
        status: status.unwrap_or_else(|| child.wait().unwrap()),
        stdout: stdout.join().unwrap(),
        stderr: stderr.join().unwrap(),
    };
    if status.is_none() {
        let args: Vec<_> = cmd.get_args().collect();
        panic!(
            "wavetrace {args:?} still running after {limit:?}, killed\n{}",
            text(&output)
        );
    }
    output
}

/// Waits for `child` to exit, at most `limit`; kills it and returns `None`
/// if it has not by then.
pub fn wait_within(child: &mut Child, limit: Duration) -> Option<std::process::ExitStatus> {
    let start = Instant::now();
    let mut nap = Duration::from_millis(1);
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return Some(status);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            return None;
        }
        std::thread::sleep(nap);
        nap = (nap * 2).min(Duration::from_millis(10));
    }
}

/// Runs `wavetrace ARGS` in `dir` (see [`wavetrace`]), killed after `limit`.
pub fn run_with_limit<S: AsRef<OsStr>>(dir: &Path, args: &[S], limit: Duration) -> Output {
    finish(&mut wavetrace(dir, args), limit)
}

/// Runs `wavetrace ARGS` in `dir` (see [`wavetrace`]), killed after
/// [`PATIENCE`].
pub fn run<S: AsRef<OsStr>>(dir: &Path, args: &[S]) -> Output {
    run_with_limit(dir, args, PATIENCE)
}

/// [`run`] with the environment variables `env` set (on top of the
/// [`SCHEDULER_VARS`] removed).
pub fn run_env<S: AsRef<OsStr>>(dir: &Path, args: &[S], env: &[(&str, &str)]) -> Output {
    finish(wavetrace(dir, args).envs(env.iter().copied()), PATIENCE)
}

/// A run that must succeed; returns its output.
pub fn run_ok<S: AsRef<OsStr> + Debug>(dir: &Path, args: &[S]) -> Output {
    let o = run(dir, args);
    assert!(
        o.status.success(),
        "wavetrace {args:?} failed: {}",
        text(&o)
    );
    o
}

/// A run that must be refused (exit non-zero); returns its stderr.
pub fn run_refused<S: AsRef<OsStr> + Debug>(dir: &Path, args: &[S]) -> String {
    let o = run(dir, args);
    assert!(!o.status.success(), "wavetrace {args:?} was not refused");
    stderr(&o)
}

/// Asserts that a run succeeded; returns its output.
pub fn ok(o: Output) -> Output {
    assert!(o.status.success(), "wavetrace failed: {}", text(&o));
    o
}

/// Asserts that a run was refused (exit non-zero); returns its stderr.
pub fn refused(o: Output) -> String {
    assert!(
        !o.status.success(),
        "wavetrace was not refused: {}",
        text(&o)
    );
    stderr(&o)
}

/// What a run wrote to stdout.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// What a run wrote to stderr.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A run's exit status, stdout and stderr, for failure messages.
pub fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout: {}\nstderr: {}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

// --- Small settings ---

/// The tiny render the command-line tests ask for: 16×12 pixels at 2
/// samples per pixel, the same render as [`tiny`].
pub const TINY: [&str; 6] = ["--width", "16", "--height", "12", "--spp", "2"];

/// `scene`'s own settings ([`RenderSettings::for_scene`]: its max depth,
/// seed 0, every core, the default engine) at `width`×`height` pixels and
/// `spp` samples per pixel.
pub fn settings(scene: &Scene, width: u32, height: u32, spp: u32) -> RenderSettings {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.spp) = (width, height, spp);
    s
}

/// The [`TINY`] render of `scene`: 16×12 pixels, 2 samples per pixel.
pub fn tiny(scene: &Scene) -> RenderSettings {
    settings(scene, 16, 12, 2)
}

/// The samples per pixel an accumulation file (checkpoint, partial file)
/// holds.
pub fn spp_of(file: &Path) -> u64 {
    Film::load(file, None).unwrap().0.samples_per_pixel()
}

/// The long render of the checkpoint and signal tests: `wavetrace` with
/// [`SETTINGS`](long_render::SETTINGS) unless the arguments give them.
pub mod long_render {
    use super::*;

    /// Small with a fixed seed; at [`SPP`] about a second of work on one
    /// thread, so that signals find it part-way.
    pub const SETTINGS: &[&str] = &[
        "--width",
        "40",
        "--height",
        "40",
        "--seed",
        "7",
        "--max-depth",
        "3",
    ];

    /// The samples per pixel of the whole render.
    pub const SPP: &str = "6000";

    /// `args` after those of [`SETTINGS`] that `args` do not give.
    pub fn args<'a>(args: &[&'a str]) -> Vec<&'a str> {
        let mut all: Vec<&str> = SETTINGS
            .chunks(2)
            .filter(|pair| !args.contains(&pair[0]))
            .flatten()
            .copied()
            .collect();
        all.extend_from_slice(args);
        all
    }

    /// `wavetrace` with [`SETTINGS`] and `args`, ready to run in `dir`
    /// (see [`wavetrace`](super::wavetrace)).
    pub fn command(dir: &Path, args: &[&str]) -> Command {
        super::wavetrace(dir, &self::args(args))
    }

    /// Runs to the end, killed after [`PATIENCE`].
    pub fn run(dir: &Path, args: &[&str]) -> Output {
        super::run(dir, &self::args(args))
    }

    /// Runs to the end, which must succeed.
    pub fn run_ok(dir: &Path, args: &[&str]) -> Output {
        let o = run(dir, args);
        assert!(
            o.status.success(),
            "wavetrace {args:?} failed: {}",
            text(&o)
        );
        o
    }
}

/// Accumulation files (`.wtacc`) written byte by byte, for the hostile-input
/// tests: any header, any data, and a valid checksum, as an attacker can
/// forge one (the checksum guards against accidents, not attacks).
pub mod forge {
    /// The magic of an accumulation file.
    pub const MAGIC: &[u8; 8] = b"WTACC\0\0\x01";

    /// A header's JSON: `format` right, the other fields as given.
    pub fn header(
        width: u64,
        height: u64,
        ranges: &[[u64; 2]],
        spp: Option<u64>,
        shard: Option<[u64; 2]>,
        settings_hash: u128,
    ) -> String {
        let ranges: Vec<String> = ranges.iter().map(|[a, b]| format!("[{a},{b}]")).collect();
        let mut h = format!(
            "{{\"format\":\"wavetrace-accumulation/1\",\"width\":{width},\"height\":{height},\
             \"settings_hash\":\"{settings_hash:032x}\",\"ranges\":[{}],\"invalid_samples\":0",
            ranges.join(",")
        );
        if let Some(spp) = spp {
            h += &format!(",\"spp\":{spp}");
        }
        if let Some([i, n]) = shard {
            h += &format!(",\"shard\":[{i},{n}]");
        }
        h + "}"
    }

    /// A file of `header` (any bytes) and `data`, with a valid checksum.
    pub fn file(header: &[u8], data: &[u8]) -> Vec<u8> {
        let mut bytes = MAGIC.to_vec();
        bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
        bytes.extend_from_slice(header);
        bytes.extend_from_slice(data);
        seal(bytes)
    }

    /// `body` (magic, header length, header, sums) with its checksum after it.
    pub fn seal(mut body: Vec<u8>) -> Vec<u8> {
        let check = xxhash_rust::xxh3::xxh3_128(&body);
        body.extend_from_slice(&check.to_le_bytes());
        body
    }

    /// The header (as text) and sums of a real file.
    pub fn split(bytes: &[u8]) -> (Vec<u8>, Vec<u8>) {
        let len = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
        let header = bytes[16..16 + len].to_vec();
        let data = bytes[16 + len..bytes.len() - 16].to_vec();
        (header, data)
    }
}

/// Every file under `dir` (in sub-folders too), by its path below `dir`,
/// with its bytes.
pub fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                out.insert(
                    p.strip_prefix(root).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// A GLB's JSON and binary chunk (the file's own lengths, unchecked).
pub fn split_glb(b: &[u8]) -> (serde_json::Value, Vec<u8>) {
    let len = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize;
    let json_len = len(12);
    let json = serde_json::from_slice(&b[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    let bin = b[bin_at + 8..bin_at + 8 + len(bin_at)].to_vec();
    (json, bin)
}

/// A GLB of `json` and `bin` (each chunk padded to 4 bytes, lengths right).
pub fn glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    j.resize(j.len().next_multiple_of(4), b' ');
    let mut b = bin.to_vec();
    b.resize(b.len().next_multiple_of(4), 0);
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

/// Every byte of `bin` from `first` on XORed with each of `flips`, and
/// `bin` cut short at each of those lengths, read as the GLB of `json`
/// with that binary chunk: each is loaded or refused naming the file,
/// never a panic, and what loads has its indices in range and finite
/// positions. Returns how many loaded and how many were refused (both
/// must happen: a mutation range that changes nothing tests nothing).
#[allow(dead_code)]
pub fn glb_mutations_never_panic(
    what: &str,
    json: &serde_json::Value,
    bin: &[u8],
    first: usize,
    flips: &[u8],
) -> (usize, usize) {
    let (mut loaded, mut refused) = (0, 0);
    for k in first..bin.len() {
        let flipped = flips.iter().map(|&x| {
            let mut b = bin.to_vec();
            b[k] ^= x;
            b
        });
        for b in flipped.chain([bin[..k].to_vec()]) {
            let r = std::panic::catch_unwind(|| {
                wavetrace::scene::gltf::read(&glb(json, &b), "test.glb", None)
            });
            match r.unwrap_or_else(|_| panic!("{what} byte {k}: a panic")) {
                Ok(a) => {
                    loaded += 1;
                    assert_asset_in_range(&a);
                }
                Err(e) => {
                    refused += 1;
                    assert!(e.to_string().starts_with("test.glb: "), "{e}");
                }
            }
        }
    }
    eprintln!("{what}: {loaded} loaded, {refused} refused");
    assert!(refused > 0 && loaded > 0, "{what}");
    (loaded, refused)
}

/// What a loaded asset promises whatever file it came from: every index
/// names a vertex of its mesh, every position is finite.
#[allow(dead_code)]
pub fn assert_asset_in_range(a: &wavetrace::scene::asset::Asset) {
    for m in &a.meshes {
        let n = m.positions.len() as u32;
        assert!(m.triangles.iter().flatten().all(|&i| i < n));
        assert!(m.positions.iter().all(|p| p.is_finite()));
    }
}

/// The GLB `bytes` read as `test.glb`, or a panic with the error.
#[allow(dead_code)]
pub fn read_glb(bytes: &[u8]) -> wavetrace::scene::asset::Asset {
    wavetrace::scene::gltf::read(bytes, "test.glb", None).unwrap_or_else(|e| panic!("{e}"))
}

/// The asset file `bytes`, written as `name` in `dir`, loaded as
/// `wavetrace FILE` loads it.
#[allow(dead_code)]
pub fn scene_of(dir: &TempDir, name: &str, bytes: &[u8]) -> Scene {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    wavetrace::scene::asset_scene::load(&path, None).unwrap().0
}

/// The reference tracer's and the wavefront engine's images of the same
/// scene agree per pixel and channel to rounding (the engines trace the
/// same paths and sum their terms in another order).
#[allow(dead_code)]
pub fn assert_engines_close(what: &str, reference: &[[f32; 3]], wavefront: &[[f32; 3]]) {
    assert_eq!(reference.len(), wavefront.len(), "{what}: image sizes");
    for (i, (pa, pb)) in reference.iter().zip(wavefront).enumerate() {
        for c in 0..3 {
            let (x, y) = (pa[c], pb[c]);
            assert!(
                (x - y).abs() <= 1e-5 * x.abs().max(y.abs()) + 1e-6,
                "{what}: pixel {i} channel {c}: reference {x}, wavefront {y}"
            );
        }
    }
}

/// A white (reflectance 1) diffuse ground square seen from straight above
/// (`position` of the camera, looking down, +X to the right), with
/// `extra` (lights, more geometry); `max_depth = 2`: each pixel is the
/// ground's direct light, `E / π`.
pub fn ground_scene(camera: [f32; 3], vfov: f32, (w, h): (u32, u32), extra: &str) -> Scene {
    let [x, y, z] = camera;
    let text = format!(
        r#"
[camera]
position = [{x:?}, {y:?}, {z:?}]
look_at = [{x:?}, 0.0, {z:?}]
up = [0.0, 0.0, -1.0]
vfov_deg = {vfov:?}
width = {w}
height = {h}
[integrator]
max_depth = 2
[materials.white]
reflectance = [1.0, 1.0, 1.0]
[[quad]]
material = "white"
vertices = [[-20.0, 0.0, 20.0], [20.0, 0.0, 20.0], [20.0, 0.0, -20.0], [-20.0, 0.0, -20.0]]
{extra}
"#
    );
    wavetrace::scene::file::parse(&text, "ground.toml").unwrap()
}
