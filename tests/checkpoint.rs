//! Long renders end to end, with the real `wavetrace` binary: interrupted by
//! SIGINT, SIGTERM and SIGKILL part-way and resumed, the image is byte for
//! byte the uninterrupted one; bad checkpoints are refused and left alone;
//! the time limit is kept to within one pass.
//!
//! The renders are tiny (16x16) so the tests take seconds; they wait for
//! files to appear rather than sleeping fixed times, so a loaded machine
//! only makes them slower.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};
use wavetrace::film::Film;

const BIN: &str = env!("CARGO_BIN_EXE_wavetrace");
/// The render every test makes: small, fixed seed; about a second of work
/// on one thread (signals must find it part-way), at 40x40 and 6000 spp.
const SETTINGS: &[&str] = &[
    "--width",
    "40",
    "--height",
    "40",
    "--seed",
    "7",
    "--max-depth",
    "3",
];
const SPP: &str = "6000";
/// How long anything may take before a test gives up.
const PATIENCE: Duration = Duration::from_secs(120);

/// A fresh, empty directory for one test.
fn workdir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("checkpoint-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `wavetrace` with [`SETTINGS`], except those that `args` give.
fn wavetrace(dir: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(BIN);
    for pair in SETTINGS.chunks(2) {
        if !args.contains(&pair[0]) {
            c.args(pair);
        }
    }
    c.current_dir(dir)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    c
}

/// Run to the end; returns the output.
fn run(dir: &Path, args: &[&str]) -> Output {
    wavetrace(dir, args).output().unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout: {}\nstderr: {}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Run to the end, which must succeed.
fn run_ok(dir: &Path, args: &[&str]) -> Output {
    let o = run(dir, args);
    assert!(
        o.status.success(),
        "wavetrace {args:?} failed: {}",
        text(&o)
    );
    o
}

/// The uninterrupted render's image bytes, per format, made once.
fn reference(ext: &str) -> Vec<u8> {
    static PNG: OnceLock<Vec<u8>> = OnceLock::new();
    static PFM: OnceLock<Vec<u8>> = OnceLock::new();
    let cell = if ext == "png" { &PNG } else { &PFM };
    cell.get_or_init(|| {
        let dir = workdir(&format!("reference-{ext}"));
        let out = format!("reference.{ext}");
        run_ok(&dir, &["--spp", SPP, "--out", &out]);
        std::fs::read(dir.join(out)).unwrap()
    })
    .clone()
}

/// A running render, killed if the test ends while it runs.
struct Render(Option<std::process::Child>);

impl Render {
    fn start(dir: &Path, args: &[&str]) -> Self {
        Self(Some(wavetrace(dir, args).spawn().unwrap()))
    }

    fn child(&mut self) -> &mut std::process::Child {
        self.0.as_mut().unwrap()
    }

    /// Wait until `path` exists while the render still runs.
    fn wait_for_file(&mut self, path: &Path) {
        let start = Instant::now();
        while !path.exists() {
            if let Some(status) = self.child().try_wait().unwrap() {
                panic!(
                    "the render ended ({status}) before {} appeared; the machine is \
                     too fast for this test's render size",
                    path.display()
                );
            }
            assert!(
                start.elapsed() < PATIENCE,
                "{} never appeared",
                path.display()
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn signal(&mut self, sig: i32) {
        let pid = self.child().id() as libc::pid_t;
        // SAFETY: kill(2) on our own child's pid; no memory is involved.
        assert_eq!(unsafe { libc::kill(pid, sig) }, 0);
    }

    fn finish(mut self) -> Output {
        let start = Instant::now();
        while self.child().try_wait().unwrap().is_none() {
            assert!(start.elapsed() < PATIENCE, "the render did not stop");
            std::thread::sleep(Duration::from_millis(5));
        }
        self.0.take().unwrap().wait_with_output().unwrap()
    }
}

impl Drop for Render {
    fn drop(&mut self) {
        if let Some(child) = &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

fn spp_of(checkpoint: &Path) -> u64 {
    Film::load(checkpoint, None).unwrap().0.samples_per_pixel()
}

/// Start a render on one thread with a checkpoint every 0.05 s, send `sig` once the first
/// checkpoint is written, and check it stopped cleanly part-way. Returns
/// the samples per pixel saved.
fn interrupt(dir: &Path, sig: i32, extra: &[&str], checkpoint: &str) -> u64 {
    let ck = dir.join(checkpoint);
    let mut args = vec!["--spp", SPP, "--checkpoint", checkpoint];
    args.extend_from_slice(&["--checkpoint-every", "0.05", "--threads", "1"]);
    args.extend_from_slice(extra);
    let mut render = Render::start(dir, &args);
    render.wait_for_file(&ck);
    render.signal(sig);
    let o = render.finish();
    assert_eq!(o.status.code(), Some(128 + sig), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("stopped by SIG"), "{}", text(&o));
    assert!(stdout.contains("checkpoint saved"), "{}", text(&o));
    let spp = spp_of(&ck);
    assert!(
        (1..6000).contains(&spp),
        "the checkpoint holds {spp} spp, not part of 6000"
    );
    spp
}

#[test]
fn sigint_then_resume_is_byte_identical() {
    let dir = workdir("sigint");
    let spp = interrupt(&dir, libc::SIGINT, &["--out", "out.png"], "ck.wtacc");
    assert!(
        !dir.join("out.png").exists(),
        "an interrupted render without --write-partial writes no image"
    );
    let o = run_ok(
        &dir,
        &[
            "--spp", SPP, "--resume", "ck.wtacc", "--out", "out.png", "--stats", "s.json",
        ],
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("resumed from ck.wtacc"));
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("s.json")).unwrap()).unwrap();
    assert_eq!(stats["spp_resumed"], spp);
    assert_eq!(stats["spp"], 6000);
    assert_eq!(
        std::fs::read(dir.join("out.png")).unwrap(),
        reference("png")
    );
    // The finished render's checkpoint holds every sample.
    assert_eq!(spp_of(&dir.join("ck.wtacc")), 6000);
}

#[test]
fn sigterm_twice_then_resume_is_byte_identical() {
    let dir = workdir("sigterm");
    let first = interrupt(&dir, libc::SIGTERM, &["--out", "out.pfm"], "a.wtacc");
    // Resume into another checkpoint file, and stop that run too; the last
    // run is on two threads.
    let second = interrupt(
        &dir,
        libc::SIGTERM,
        &["--resume", "a.wtacc", "--out", "out.pfm"],
        "b.wtacc",
    );
    assert!(second > first, "the resumed run added samples");
    assert_eq!(
        spp_of(&dir.join("a.wtacc")),
        first,
        "a.wtacc was left alone"
    );
    run_ok(
        &dir,
        &[
            "--spp",
            SPP,
            "--resume",
            "b.wtacc",
            "--out",
            "out.pfm",
            "--threads",
            "2",
        ],
    );
    assert_eq!(
        std::fs::read(dir.join("out.pfm")).unwrap(),
        reference("pfm")
    );
}

#[test]
fn sigkill_leaves_a_checkpoint_that_resumes_byte_identical() {
    let dir = workdir("sigkill");
    let ck = dir.join("ck.wtacc");
    let mut render = Render::start(
        &dir,
        &[
            "--spp",
            SPP,
            "--threads",
            "1",
            "--out",
            "out.pfm",
            "--checkpoint",
            "ck.wtacc",
            "--checkpoint-every",
            "0.05",
        ],
    );
    render.wait_for_file(&ck);
    // Let it overwrite the checkpoint a few times, then kill it without
    // warning, possibly in the middle of writing one.
    std::thread::sleep(Duration::from_millis(120));
    render.signal(libc::SIGKILL);
    let o = render.finish();
    assert_eq!(o.status.code(), None, "killed: {}", text(&o));
    let spp = spp_of(&ck);
    assert!((1..6000).contains(&spp), "{spp}");
    run_ok(
        &dir,
        &["--spp", SPP, "--resume", "ck.wtacc", "--out", "out.pfm"],
    );
    assert_eq!(
        std::fs::read(dir.join("out.pfm")).unwrap(),
        reference("pfm")
    );
}

#[test]
fn partial_images_are_whole_and_exact() {
    let dir = workdir("partial");
    let out = dir.join("out.pfm");
    let mut render = Render::start(
        &dir,
        &[
            "--spp",
            SPP,
            "--threads",
            "1",
            "--out",
            "out.pfm",
            "--write-partial",
            "0.05",
            "--checkpoint",
            "ck.wtacc",
            "--checkpoint-every",
            "1000",
        ],
    );
    render.wait_for_file(&out);
    render.signal(libc::SIGINT);
    let o = render.finish();
    assert_eq!(o.status.code(), Some(130), "{}", text(&o));
    // On the signal the partial image is brought up to the checkpoint: it is
    // exactly the image of the samples saved.
    let spp = spp_of(&dir.join("ck.wtacc")).to_string();
    run_ok(&dir, &["--spp", &spp, "--out", "exact.pfm"]);
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(dir.join("exact.pfm")).unwrap()
    );
}

/// A finished 8-spp render's checkpoint, made in `dir`.
fn small_checkpoint(dir: &Path) -> PathBuf {
    run_ok(
        dir,
        &[
            "--spp",
            "8",
            "--out",
            "small.png",
            "--checkpoint",
            "ck.wtacc",
        ],
    );
    dir.join("ck.wtacc")
}

/// Resuming `ck` with `args` must fail with `message`, before any work:
/// nothing written, the checkpoint untouched.
fn refused(dir: &Path, ck: &Path, args: &[&str], message: &str) {
    let before = std::fs::read(ck).unwrap();
    let modified = std::fs::metadata(ck).unwrap().modified().unwrap();
    let mut all = vec![
        "--resume",
        "ck.wtacc",
        "--spp",
        "16",
        "--out",
        "refused.png",
    ];
    all.extend_from_slice(args);
    let o = run(dir, &all);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains(message),
        "expected {message:?}: {}",
        text(&o)
    );
    assert!(
        stderr.contains("ck.wtacc"),
        "the error names the file: {stderr}"
    );
    assert_eq!(std::fs::read(ck).unwrap(), before, "checkpoint changed");
    assert_eq!(std::fs::metadata(ck).unwrap().modified().unwrap(), modified);
    assert!(!dir.join("refused.png").exists());
}

#[test]
fn corrupt_or_truncated_checkpoints_are_refused_and_untouched() {
    let dir = workdir("corrupt");
    let ck = small_checkpoint(&dir);
    let good = std::fs::read(&ck).unwrap();

    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x10;
    std::fs::write(&ck, &flipped).unwrap();
    refused(
        &dir,
        &ck,
        &[],
        "checksum mismatch: the file is truncated or corrupt",
    );

    std::fs::write(&ck, &good[..good.len() - 100]).unwrap();
    refused(&dir, &ck, &[], "truncated or corrupt");

    std::fs::write(&ck, &good[..10]).unwrap();
    refused(&dir, &ck, &[], "not a wavetrace accumulation file");

    std::fs::write(&ck, b"").unwrap();
    refused(&dir, &ck, &[], "not a wavetrace accumulation file");

    // The good file still resumes.
    std::fs::write(&ck, &good).unwrap();
    run_ok(
        &dir,
        &["--resume", "ck.wtacc", "--spp", "16", "--out", "ok.png"],
    );
}

#[test]
fn checkpoints_of_other_settings_or_scenes_are_refused_and_untouched() {
    let dir = workdir("other");
    let ck = small_checkpoint(&dir);
    let other = "made by a render of another scene or other settings";
    refused(&dir, &ck, &["--seed", "8"], other);
    refused(&dir, &ck, &["--max-depth", "2"], other);
    refused(&dir, &ck, &["--width", "17"], other);
    // Another scene: the Cornell box with one colour changed.
    let scene =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell.toml"))
            .unwrap()
            .replacen("[0.15, 0.75, 0.15]", "[0.15, 0.75, 0.16]", 1);
    std::fs::write(dir.join("green.toml"), scene).unwrap();
    refused(&dir, &ck, &["green.toml"], other);
    // Fewer samples than it holds.
    let before = std::fs::read(&ck).unwrap();
    let o = run(
        &dir,
        &["--resume", "ck.wtacc", "--spp", "4", "--out", "refused.png"],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("more than --spp 4"),
        "{}",
        text(&o)
    );
    assert_eq!(std::fs::read(&ck).unwrap(), before);
}

#[test]
fn time_limit_is_honoured_within_one_pass() {
    let dir = workdir("time-limit");
    let start = Instant::now();
    let o = run_ok(
        &dir,
        &[
            "--spp",
            "1000000",
            "--time-limit",
            "1",
            "--out",
            "out.pfm",
            "--stats",
            "s.json",
        ],
    );
    let wall = start.elapsed().as_secs_f64();
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("s.json")).unwrap()).unwrap();
    assert_eq!(s["stop"], "time-limit", "{}", text(&o));
    assert_eq!(s["time_limit_seconds"], 1.0);
    let spp = s["spp"].as_u64().unwrap();
    assert!((1..1_000_000).contains(&spp));
    let elapsed = s["elapsed_seconds"].as_f64().unwrap();
    let pass = s["longest_pass_seconds"].as_f64().unwrap();
    assert!(
        elapsed <= 1.0 + pass,
        "rendered for {elapsed} s; the limit is 1 s and the longest pass {pass} s"
    );
    assert!(
        wall < 1.0 + pass + 5.0,
        "the process took {wall} s for a 1 s limit"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("(time limit)"));
    // The image holds exactly the samples it says.
    run_ok(&dir, &["--spp", &spp.to_string(), "--out", "exact.pfm"]);
    assert_eq!(
        std::fs::read(dir.join("out.pfm")).unwrap(),
        std::fs::read(dir.join("exact.pfm")).unwrap()
    );
}

#[test]
fn impossible_long_render_settings_are_refused_before_any_work() {
    let dir = workdir("impossible");
    std::fs::write(dir.join("exists.wtacc"), b"precious").unwrap();
    for (args, message) in [
        (
            &["--checkpoint", "c.wtacc", "--checkpoint-every", "0"][..],
            "positive number of seconds",
        ),
        (&["--time-limit=-1"], "positive number of seconds"),
        (&["--write-partial", "nan"], "positive number of seconds"),
        (&["--time-limit", "soon"], "not a number of seconds"),
        (
            &["--checkpoint-every", "5"],
            "--checkpoint-every needs --checkpoint",
        ),
        (&["--resume", "missing.wtacc"], "missing.wtacc: cannot read"),
        (
            &["--checkpoint", "exists.wtacc"],
            "continue it with --resume exists.wtacc",
        ),
        (&["--checkpoint", "out.png"], "cannot be the output image"),
        (
            &["--checkpoint", "no/such/dir/c.wtacc"],
            "no/such/dir/c.wtacc",
        ),
    ] {
        let mut all = vec!["--spp", "100000", "--out", "out.png"];
        all.extend_from_slice(args);
        let start = Instant::now();
        let o = run(&dir, &all);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(message),
            "{args:?}: expected {message:?}: {}",
            text(&o)
        );
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "{args:?} did work"
        );
        assert!(!dir.join("out.png").exists());
        assert!(!dir.join("c.wtacc").exists());
    }
    assert_eq!(
        std::fs::read(dir.join("exists.wtacc")).unwrap(),
        b"precious"
    );
}

#[test]
fn a_finished_checkpoint_extends_to_more_samples() {
    let dir = workdir("extend");
    run_ok(
        &dir,
        &["--spp", "100", "--out", "a.pfm", "--checkpoint", "ck.wtacc"],
    );
    run_ok(
        &dir,
        &["--spp", "300", "--out", "a.pfm", "--resume", "ck.wtacc"],
    );
    run_ok(&dir, &["--spp", "300", "--out", "b.pfm"]);
    assert_eq!(
        std::fs::read(dir.join("a.pfm")).unwrap(),
        std::fs::read(dir.join("b.pfm")).unwrap()
    );
    assert_eq!(spp_of(&dir.join("ck.wtacc")), 300);
}

/// A shard is rendered by the same session as a whole render: stopped by
/// SIGINT part-way, its checkpoint is a partial file of the shard's samples
/// so far (the shard in its header); resumed, the shard's partial file is
/// the finished checkpoint byte for byte, and merged with the other shard
/// it gives the uninterrupted single run's image byte for byte. Resuming
/// as another shard is refused, the checkpoint left untouched.
#[test]
fn a_shard_stopped_by_sigint_resumes_and_merges_byte_identical() {
    let dir = workdir("shard");
    let spp = interrupt(
        &dir,
        libc::SIGINT,
        &["--shard", "1/2", "--partial", "part-1.wtacc"],
        "ck-1.wtacc",
    );
    assert!(spp < 3000, "shard 1/2 holds at most 3000 samples");
    assert!(
        !dir.join("part-1.wtacc").exists(),
        "an interrupted shard writes no partial file"
    );
    let (film, meta) = Film::load_with_meta(&dir.join("ck-1.wtacc"), None).unwrap();
    assert_eq!(meta.shard, Some((1, 2)));
    assert_eq!(meta.spp, Some(6000));
    assert_eq!(film.ranges.first().unwrap().start, 3000);
    assert!(film.ranges.last().unwrap().end <= 6000);

    // Not as another shard, nor as a whole render of fewer samples.
    let ck = dir.join("ck-1.wtacc");
    let before = std::fs::read(&ck).unwrap();
    for (args, message) in [
        (
            &["--shard", "0/2", "--spp", SPP][..],
            "outside samples 0..3000 of 6000",
        ),
        (&["--samples", "0..3000", "--spp", SPP], "outside samples"),
        (&["--spp", "3000"], "more than --spp 3000"),
    ] {
        let mut all = vec!["--resume", "ck-1.wtacc", "--partial", "other.wtacc"];
        all.extend_from_slice(args);
        let o = run(&dir, &all);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", text(&o));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            stderr.contains("ck-1.wtacc") && stderr.contains(message),
            "{args:?}: expected {message:?}: {}",
            text(&o)
        );
        assert!(!dir.join("other.wtacc").exists());
    }
    assert_eq!(std::fs::read(&ck).unwrap(), before, "checkpoint changed");

    let o = run_ok(
        &dir,
        &[
            "--spp",
            SPP,
            "--shard",
            "1/2",
            "--resume",
            "ck-1.wtacc",
            "--partial",
            "part-1.wtacc",
            "--threads",
            "2",
            "--stats",
            "s.json",
        ],
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("(samples 3000..6000 of 0..6000, shard 1/2)")
            && stdout.contains("resumed from ck-1.wtacc"),
        "{}",
        text(&o)
    );
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("s.json")).unwrap()).unwrap();
    assert_eq!(stats["spp"], 3000);
    assert_eq!(stats["spp_resumed"], spp);
    assert_eq!(stats["spp_requested"], 6000);
    assert_eq!(stats["samples"], serde_json::json!([3000, 6000]));
    assert_eq!(stats["shard"], serde_json::json!([1, 2]));
    assert_eq!(stats["output"], "part-1.wtacc");
    assert_eq!(stats["partial"], "part-1.wtacc");
    assert_eq!(stats["stop"], "complete");
    // Checkpoints and partial files are one format: the finished shard's
    // checkpoint is its partial file.
    assert_eq!(
        std::fs::read(dir.join("part-1.wtacc")).unwrap(),
        std::fs::read(&ck).unwrap()
    );

    run_ok(
        &dir,
        &["--spp", SPP, "--shard", "0/2", "--partial", "part-0.wtacc"],
    );
    let o = Command::new(BIN)
        .current_dir(&dir)
        .args([
            "merge",
            "part-1.wtacc",
            "part-0.wtacc",
            "--out",
            "merged.png",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        std::fs::read(dir.join("merged.png")).unwrap(),
        reference("png")
    );
}

/// --time-limit on a shard: its partial file holds the whole passes done,
/// and the stats say which samples of which shard.
#[test]
fn a_shard_keeps_its_time_limit() {
    let dir = workdir("shard-time-limit");
    let o = run_ok(
        &dir,
        &[
            "--spp",
            "4000000",
            "--shard",
            "3/4",
            "--time-limit",
            "0.5",
            "--partial",
            "part-3.wtacc",
            "--stats",
            "s.json",
        ],
    );
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("s.json")).unwrap()).unwrap();
    assert_eq!(s["stop"], "time-limit", "{}", text(&o));
    assert_eq!(s["samples"], serde_json::json!([3000000, 4000000]));
    let spp = s["spp"].as_u64().unwrap();
    assert!((1..1_000_000).contains(&spp), "{spp}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains(&format!("rendered {spp} spp of 1000000 (time limit)")),
        "{}",
        text(&o)
    );
    let (film, meta) = Film::load_with_meta(&dir.join("part-3.wtacc"), None).unwrap();
    assert_eq!(film.ranges.len(), 1);
    assert_eq!(film.ranges[0], 3000000..3000000 + spp as u32);
    assert_eq!(meta.shard, Some((3, 4)));
}
