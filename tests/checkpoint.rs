//! Checkpoints end to end, with the real `wavetrace` binary: bad
//! checkpoints (corrupt, truncated, of other settings or scenes) are refused
//! and left alone, impossible long-render settings are refused before any
//! work, and a finished checkpoint extends to more samples exactly.
//!
//! These are the fast checkpoint tests. The slow ones, which stop a running
//! render with SIGINT, SIGTERM or SIGKILL or wait on a time limit, are in
//! `signals.rs`.

mod common;

use common::long_render::{run, run_ok};
use common::{TempDir, spp_of, text};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

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
    let dir = TempDir::new("corrupt");
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
    let dir = TempDir::new("other");
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
fn impossible_long_render_settings_are_refused_before_any_work() {
    let dir = TempDir::new("impossible");
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
    let dir = TempDir::new("extend");
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
