//! The slow, signal-driven suite. Long renders end to end, with the real
//! `wavetrace` binary: interrupted by SIGINT, SIGTERM and SIGKILL part-way
//! and resumed, the image is byte for byte the uninterrupted one; partial
//! images are exact; the time limit is kept to within one pass; a shard
//! stopped part-way resumes and merges byte for byte.
//!
//! Every test here starts a render of about a second, signals it or lets a
//! time limit stop it, and waits, so this suite takes longer than any other
//! test file. CI runs it with them (plain `cargo test --release`);
//! `cargo test --release --test signals` runs it alone. The fast checkpoint
//! tests (bad checkpoints refused, impossible settings refused, a finished
//! checkpoint extended) are in `checkpoint.rs`.
//!
//! The renders are small (40x40, `common::long_render`); the tests wait for
//! files to appear rather than sleeping fixed times, so a loaded machine
//! only makes them slower.

mod common;

use common::long_render::{self, SPP, run, run_ok};
use common::{PATIENCE, TempDir, spp_of, text};
use std::path::Path;
use std::process::Output;
use std::sync::OnceLock;
use std::time::{Duration, Instant};
use wavetrace::film::Film;

/// The uninterrupted render's image bytes, per format, made once.
fn reference(ext: &str) -> Vec<u8> {
    static PNG: OnceLock<Vec<u8>> = OnceLock::new();
    static PFM: OnceLock<Vec<u8>> = OnceLock::new();
    let cell = if ext == "png" { &PNG } else { &PFM };
    cell.get_or_init(|| {
        let dir = TempDir::new(&format!("reference-{ext}"));
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
        Self(Some(long_render::command(dir, args).spawn().unwrap()))
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
    let dir = TempDir::new("sigint");
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
    let dir = TempDir::new("sigterm");
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
    let dir = TempDir::new("sigkill");
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
    let dir = TempDir::new("partial");
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

#[test]
fn time_limit_is_honoured_within_one_pass() {
    let dir = TempDir::new("time-limit");
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

/// A shard is rendered by the same session as a whole render: stopped by
/// SIGINT part-way, its checkpoint is a partial file of the shard's samples
/// so far (the shard in its header); resumed, the shard's partial file is
/// the finished checkpoint byte for byte, and merged with the other shard
/// it gives the uninterrupted single run's image byte for byte. Resuming
/// as another shard is refused, the checkpoint left untouched.
#[test]
fn a_shard_stopped_by_sigint_resumes_and_merges_byte_identical() {
    let dir = TempDir::new("shard");
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
    // A merge, which takes no render settings.
    let o = common::run(
        &dir,
        &[
            "merge",
            "part-1.wtacc",
            "part-0.wtacc",
            "--out",
            "merged.png",
        ],
    );
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
    let dir = TempDir::new("shard-time-limit");
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
