//! Farm rendering end to end through the `wavetrace` binary: shards by
//! sample range, `--shard auto` from a scheduler's environment, threads from
//! `SLURM_CPUS_PER_TASK`, and `wavetrace merge` with each of its refusals.
//! Small images (16x16, 16 spp) keep every test fast.

// Films hold lists of sample ranges; a list of one range is what is meant.
#![allow(clippy::single_range_in_vec_init)]

mod common;

use common::{TempDir, ok, p, refused, run, run_env, run_ok, run_refused};
use std::path::{Path, PathBuf};
use std::process::Output;
use wavetrace::film::Film;
use wavetrace::render::Renderer;
use wavetrace::scene::Scene;

const SMALL: &[&str] = &["--width", "16", "--height", "16", "--spp", "16"];

/// Render shard `i` of `n` of the SMALL render into `dir/part-i.wtacc`.
fn shard(dir: &Path, i: u32, n: u32, extra: &[&str]) -> PathBuf {
    let part = dir.join(format!("part-{i}.wtacc"));
    let spec = format!("{i}/{n}");
    let mut args = vec!["render"];
    args.extend_from_slice(SMALL);
    args.extend_from_slice(&["--shard", &spec, "--partial", p(&part)]);
    args.extend_from_slice(extra);
    run_ok(dir, &args);
    part
}

/// A single run of the SMALL render: `dir/single.png` and `.wtacc`.
fn single(dir: &Path) -> (PathBuf, PathBuf) {
    let (png, acc) = (dir.join("single.png"), dir.join("single.wtacc"));
    let mut args = vec!["render"];
    args.extend_from_slice(SMALL);
    args.extend_from_slice(&["--out", p(&png), "--partial", p(&acc)]);
    run_ok(dir, &args);
    (png, acc)
}

/// `wavetrace merge PARTS EXTRA`, run in `dir`.
fn merge(dir: &Path, parts: &[PathBuf], extra: &[&str]) -> Output {
    let mut args = vec!["merge"];
    args.extend(parts.iter().map(|x| p(x)));
    args.extend_from_slice(extra);
    run(dir, &args)
}

fn ranges_of(path: &Path) -> Vec<std::ops::Range<u32>> {
    Film::load(path, None).unwrap().0.ranges
}

#[test]
fn merged_shards_equal_a_single_run_byte_for_byte() {
    let dir = TempDir::new("equal");
    let (single_png, single_acc) = single(&dir);
    // Given out of order, with an uneven split (16 = 5 + 5 + 6) as well.
    for n in [4, 3] {
        let shards = dir.join(format!("of{n}"));
        std::fs::create_dir_all(&shards).unwrap();
        let parts: Vec<PathBuf> = (0..n).rev().map(|i| shard(&shards, i, n, &[])).collect();
        let (png, acc) = (
            dir.join(format!("m{n}.png")),
            dir.join(format!("m{n}.wtacc")),
        );
        ok(merge(
            &dir,
            &parts,
            &["--out", p(&png), "--partial", p(&acc)],
        ));
        assert_eq!(
            std::fs::read(&png).unwrap(),
            std::fs::read(&single_png).unwrap()
        );
        assert_eq!(
            std::fs::read(&acc).unwrap(),
            std::fs::read(&single_acc).unwrap()
        );
        // The films' sums, not just the 8-bit image.
        assert_eq!(
            Film::load(&acc, None).unwrap(),
            Film::load(&single_acc, None).unwrap()
        );
    }
    // Any output format, and a merged partial file as --out.
    let parts: Vec<PathBuf> = (0..4)
        .map(|i| dir.join(format!("of4/part-{i}.wtacc")))
        .collect();
    let (pfm, acc) = (dir.join("m.pfm"), dir.join("m.wtacc"));
    ok(merge(&dir, &parts, &["--out", p(&pfm)]));
    ok(merge(&dir, &parts, &["--out", p(&acc)]));
    assert_eq!(
        std::fs::read(&acc).unwrap(),
        std::fs::read(&single_acc).unwrap()
    );
    let single_pfm = dir.join("single.pfm");
    let mut args = vec!["render"];
    args.extend_from_slice(SMALL);
    args.extend_from_slice(&["--out", p(&single_pfm)]);
    run_ok(&dir, &args);
    assert_eq!(
        std::fs::read(&pfm).unwrap(),
        std::fs::read(&single_pfm).unwrap()
    );
}

#[test]
fn library_merge_of_sample_ranges_equals_one_render() {
    let scene = Scene::cornell();
    let mut settings = common::settings(&scene, 12, 10, 13);
    settings.threads = 2;
    let renderer = Renderer::new(&scene, &settings).unwrap();
    let (whole, _, _) = renderer.render();
    let mut merged = renderer.new_film();
    for range in [7..13, 0..3, 3..7] {
        let mut part = renderer.new_film();
        renderer.render_samples(range, &mut part);
        merged.merge(&part).unwrap();
    }
    assert_eq!(merged, whole);
    assert_eq!(merged.ranges, vec![0..13]);
}

#[test]
fn shard_ranges_cover_spp_exactly() {
    let dir = TempDir::new("cover");
    for n in [1, 3, 4, 7, 16] {
        let mut all: Vec<_> = (0..n)
            .map(|i| {
                let part = shard(&dir, i, n, &[]);
                let (film, meta) = Film::load_with_meta(&part, None).unwrap();
                assert_eq!(meta.spp, Some(16));
                assert_eq!(meta.shard, Some((i, n)));
                assert_eq!(film.ranges.len(), 1);
                film.ranges[0].clone()
            })
            .collect();
        all.sort_by_key(|r| r.start);
        assert_eq!(all[0].start, 0, "{n} shards");
        assert_eq!(all.last().unwrap().end, 16, "{n} shards");
        for w in all.windows(2) {
            assert_eq!(w[0].end, w[1].start, "{n} shards: {all:?}");
        }
        let lens: Vec<u32> = all.iter().map(|r| r.end - r.start).collect();
        assert!(lens.iter().max().unwrap() - lens.iter().min().unwrap() <= 1);
    }
    // --samples renders exactly the range asked for.
    let part = dir.join("samples.wtacc");
    let mut args = vec!["render"];
    args.extend_from_slice(SMALL);
    args.extend_from_slice(&["--samples", "3..11", "--partial", p(&part)]);
    run_ok(&dir, &args);
    assert_eq!(ranges_of(&part), vec![3..11]);
}

#[test]
fn shard_auto_follows_slurm_and_kubernetes() {
    let dir = TempDir::new("auto");
    let part = dir.join("auto.wtacc");
    let run = |extra: &[&str], env: &[(&str, &str)]| {
        let mut args = vec!["render"];
        args.extend_from_slice(SMALL);
        args.extend_from_slice(&["--shard", "auto", "--partial", p(&part)]);
        args.extend_from_slice(extra);
        ok(run_env(&dir, &args, env));
        Film::load_with_meta(&part, None).unwrap()
    };
    // A Slurm array --array=1-4: task 3 is shard 2 of 4.
    let slurm = [
        ("SLURM_ARRAY_TASK_ID", "3"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_MAX", "4"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ];
    let (film, meta) = run(&[], &slurm);
    assert_eq!((film.ranges, meta.shard), (vec![8..12], Some((2, 4))));
    // A rerun of task 2 alone (--array=2) with --shard-count: shard 2 of 4.
    let rerun = [
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_MIN", "2"),
        ("SLURM_ARRAY_TASK_MAX", "2"),
        ("SLURM_ARRAY_TASK_COUNT", "1"),
    ];
    let (film, meta) = run(&["--shard-count", "4"], &rerun);
    assert_eq!((film.ranges, meta.shard), (vec![8..12], Some((2, 4))));
    // A Kubernetes Indexed Job.
    let (film, meta) = run(&["--shard-count", "8"], &[("JOB_COMPLETION_INDEX", "7")]);
    assert_eq!((film.ranges, meta.shard), (vec![14..16], Some((7, 8))));

    let part_str = p(&part).to_string();
    let auto = |extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = ["render"]
            .iter()
            .chain(SMALL)
            .map(|x| x.to_string())
            .collect();
        a.extend(["--shard", "auto", "--partial", &part_str].map(String::from));
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let _ = std::fs::remove_file(&part);
    let e = run_refused(&dir, &auto(&[]));
    assert!(
        e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"),
        "{e}"
    );
    let e = refused(run_env(&dir, &auto(&[]), &[("JOB_COMPLETION_INDEX", "1")]));
    assert!(e.contains("--shard-count"), "{e}");
    let e = refused(run_env(
        &dir,
        &auto(&["--shard-count", "4"]),
        &[("JOB_COMPLETION_INDEX", "4")],
    ));
    assert!(e.contains("not below the shard count 4"), "{e}");
    let sparse = [
        ("SLURM_ARRAY_TASK_ID", "4"),
        ("SLURM_ARRAY_TASK_MIN", "0"),
        ("SLURM_ARRAY_TASK_MAX", "4"),
        ("SLURM_ARRAY_TASK_COUNT", "3"),
        ("SLURM_ARRAY_TASK_STEP", "2"),
    ];
    let e = refused(run_env(&dir, &auto(&[]), &sparse));
    assert!(
        e.contains("not contiguous") && e.contains("--shard-count"),
        "{e}"
    );
    assert!(!part.exists(), "a refused render wrote its partial file");
}

#[test]
fn threads_follow_slurm_cpus_per_task() {
    let dir = TempDir::new("threads");
    let stats = dir.join("stats.json");
    let out = dir.join("t.png");
    let threads_of = |extra: &[&str], env: &[(&str, &str)]| {
        let mut args = vec!["render"];
        args.extend_from_slice(SMALL);
        args.extend_from_slice(&["--out", p(&out), "--stats", p(&stats)]);
        args.extend_from_slice(extra);
        ok(run_env(&dir, &args, env));
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        json["threads"].as_u64().unwrap()
    };
    assert_eq!(threads_of(&[], &[("SLURM_CPUS_PER_TASK", "3")]), 3);
    assert_eq!(
        threads_of(&["--threads", "2"], &[("SLURM_CPUS_PER_TASK", "3")]),
        2
    );
    let e = refused(run_env(
        &dir,
        &["render", "--out", p(&out)],
        &[("SLURM_CPUS_PER_TASK", "lots")],
    ));
    assert!(e.contains("SLURM_CPUS_PER_TASK"), "{e}");
}

#[test]
fn impossible_shards_are_refused_before_work() {
    let dir = TempDir::new("refuse");
    let part = dir.join("x.wtacc");
    let render = |extra: &[&str]| {
        let mut args = vec!["render"];
        args.extend_from_slice(SMALL);
        args.extend_from_slice(extra);
        run_refused(&dir, &args)
    };
    let cases: &[(&[&str], &str)] = &[
        (
            &["--shard", "4/4", "--partial", p(&part)],
            "not below the shard count",
        ),
        (&["--shard", "0/0", "--partial", p(&part)], "at least 1"),
        (&["--shard", "1-4", "--partial", p(&part)], "expected I/N"),
        (
            &["--shard", "3/17", "--partial", p(&part)],
            "at most 16 shards",
        ),
        (&["--samples", "8..4", "--partial", p(&part)], "A < B"),
        (&["--samples", "8..8", "--partial", p(&part)], "A < B"),
        (
            &["--samples", "0..17", "--partial", p(&part)],
            "beyond the 16 samples",
        ),
        (&["--shard", "1/4"], "--partial"),
        (&["--shard", "1/4", "--partial", "x.png"], ".wtacc"),
        (
            &[
                "--shard",
                "1/4",
                "--shard-count",
                "4",
                "--partial",
                p(&part),
            ],
            "--shard auto",
        ),
        (
            &["--samples", "0..4", "--shard", "1/4", "--partial", p(&part)],
            "cannot be used with",
        ),
    ];
    for (args, expected) in cases {
        let e = render(args);
        assert!(e.contains(expected), "{args:?}: {e}");
    }
    assert!(!part.exists());
}

#[test]
fn merge_refuses_overlaps_naming_the_file() {
    let dir = TempDir::new("overlap");
    let parts: Vec<PathBuf> = (0..4).map(|i| shard(&dir, i, 4, &[])).collect();
    let out = dir.join("out.png");
    // The same part twice.
    let mut twice = parts.clone();
    twice.push(parts[1].clone());
    let e = String::from_utf8(merge(&dir, &twice, &["--out", p(&out)]).stderr).unwrap();
    assert!(e.contains("part-1.wtacc") && e.contains("overlap"), "{e}");
    // Shards of different counts: 0/2 holds 0..8, part-1 of 4 holds 4..8.
    let other = dir.join("half");
    std::fs::create_dir_all(&other).unwrap();
    let half = shard(&other, 0, 2, &[]);
    let e = String::from_utf8(merge(&dir, &[half, parts[1].clone()], &["--out", p(&out)]).stderr)
        .unwrap();
    assert!(
        e.contains("part-1.wtacc: samples 4..8 overlap samples 0..8"),
        "{e}"
    );
    assert!(!out.exists(), "a refused merge wrote its output");
}

#[test]
fn merge_refuses_missing_samples_naming_the_shards() {
    let dir = TempDir::new("missing");
    let parts: Vec<PathBuf> = [0, 2].iter().map(|&i| shard(&dir, i, 4, &[])).collect();
    let (out, acc) = (dir.join("out.png"), dir.join("out.wtacc"));
    let o = merge(&dir, &parts, &["--out", p(&out), "--partial", p(&acc)]);
    assert!(!o.status.success());
    let e = String::from_utf8(o.stderr).unwrap();
    assert!(e.contains("missing samples 4..8, 12..16 of 0..16"), "{e}");
    assert!(
        e.contains("shard(s) 1, 3 of 4") && e.contains("--array=1,3"),
        "{e}"
    );
    assert!(e.contains("--allow-partial"), "{e}");
    assert!(
        !out.exists() && !acc.exists(),
        "a refused merge wrote its output"
    );
    // A missing file is named too.
    let gone = dir.join("part-1.wtacc");
    let e = String::from_utf8(merge(&dir, &[parts[0].clone(), gone], &["--out", p(&out)]).stderr)
        .unwrap();
    assert!(e.contains("part-1.wtacc: cannot read"), "{e}");
}

#[test]
fn merge_of_parts_of_different_shard_counts_gives_no_wrong_advice() {
    // Shard 0/2 (samples 0..8) and shard 3/4 (12..16): 8..12 is missing,
    // which is no one shard of either count.
    let dir = TempDir::new("mixed");
    let half = dir.join("half");
    std::fs::create_dir_all(&half).unwrap();
    let parts = [shard(&half, 0, 2, &[]), shard(&dir, 3, 4, &[])];
    let out = dir.join("out.png");
    let o = merge(&dir, &parts, &["--out", p(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8(o.stderr).unwrap();
    assert!(e.contains("missing samples 8..12 of 0..16"), "{e}");
    assert!(!e.contains("--array"), "advice from one part's count: {e}");
    assert!(!out.exists());
}

#[test]
fn allow_partial_writes_and_says_what_is_missing() {
    let dir = TempDir::new("allow");
    let parts: Vec<PathBuf> = [0, 1, 3].iter().map(|&i| shard(&dir, i, 4, &[])).collect();
    let (out, acc) = (dir.join("out.png"), dir.join("out.wtacc"));
    let o = ok(merge(
        &dir,
        &parts,
        &["--out", p(&out), "--partial", p(&acc), "--allow-partial"],
    ));
    let e = String::from_utf8(o.stderr).unwrap();
    assert!(
        e.contains("missing samples 8..12 of 0..16") && e.contains("shard(s) 2 of 4"),
        "{e}"
    );
    assert!(out.exists());
    assert_eq!(ranges_of(&acc), vec![0..8, 12..16]);
    // The merged partial file plus the missing shard make the whole render.
    let last = shard(&dir, 2, 4, &[]);
    let whole = dir.join("whole.wtacc");
    ok(merge(&dir, &[acc, last], &["--out", p(&whole)]));
    let (_, single_acc) = single(&dir);
    assert_eq!(
        std::fs::read(&whole).unwrap(),
        std::fs::read(&single_acc).unwrap()
    );
}

#[test]
fn merge_refuses_other_settings_naming_the_file() {
    let dir = TempDir::new("settings");
    let parts: Vec<PathBuf> = (0..4).map(|i| shard(&dir, i, 4, &[])).collect();
    let out = dir.join("out.png");
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    // Another scene: the Cornell box with a greener floor.
    let scene = other.join("green.toml");
    let text = std::fs::read_to_string("scenes/cornell.toml").unwrap();
    let green = text.replace("[0.15, 0.75, 0.15]", "[0.15, 0.80, 0.15]");
    assert_ne!(green, text);
    std::fs::write(&scene, green).unwrap();
    // Shard 1 of 4 of another seed, depth, scene or size.
    let base = ["render", "--height", "16", "--spp", "16"];
    let variants: &[&[&str]] = &[
        &["--width", "16", "--seed", "6"],
        &["--width", "16", "--max-depth", "2"],
        &["--width", "16", p(&scene)],
        &["--width", "17"],
    ];
    for (k, extra) in variants.iter().enumerate() {
        let odd = other.join(format!("odd-{k}.wtacc"));
        let args = [&base[..], extra, &["--shard", "1/4", "--partial", p(&odd)]].concat();
        run_ok(&dir, &args);
        let mut mixed = parts.clone();
        mixed[1] = odd;
        let e = String::from_utf8(merge(&dir, &mixed, &["--out", p(&out)]).stderr).unwrap();
        assert!(
            e.contains(&format!(
                "odd-{k}.wtacc: made by a render of another scene or other settings than"
            )),
            "{extra:?}: {e}"
        );
    }
    // Samples 4..8, as shard 1 of 4 holds, but of a 32-spp render.
    let odd = other.join("spp.wtacc");
    let args = ["render", "--width", "16", "--height", "16", "--spp", "32"];
    run_ok(
        &dir,
        &[&args[..], &["--samples", "4..8", "--partial", p(&odd)]].concat(),
    );
    let mut mixed = parts.clone();
    mixed[1] = odd;
    let e = String::from_utf8(merge(&dir, &mixed, &["--out", p(&out)]).stderr).unwrap();
    assert!(
        e.contains("spp.wtacc") && e.contains("32 samples per pixel"),
        "{e}"
    );
    assert!(!out.exists(), "a refused merge wrote its output");
}

#[test]
fn merge_refuses_truncated_and_corrupt_files_naming_them() {
    let dir = TempDir::new("truncated");
    let parts: Vec<PathBuf> = (0..4).map(|i| shard(&dir, i, 4, &[])).collect();
    let out = dir.join("out.png");
    let bytes = std::fs::read(&parts[2]).unwrap();
    let cut = dir.join("cut.wtacc");
    for len in [0, 10, 100, bytes.len() / 2, bytes.len() - 1] {
        std::fs::write(&cut, &bytes[..len]).unwrap();
        let mut mixed = parts.clone();
        mixed[2] = cut.clone();
        let e = String::from_utf8(merge(&dir, &mixed, &["--out", p(&out)]).stderr).unwrap();
        assert!(e.contains("cut.wtacc:"), "{len} bytes: {e}");
        assert!(!out.exists());
    }
    let mut flipped = bytes.clone();
    flipped[bytes.len() / 2] ^= 1;
    std::fs::write(&cut, &flipped).unwrap();
    let mut mixed = parts.clone();
    mixed[2] = cut.clone();
    let e = String::from_utf8(merge(&dir, &mixed, &["--out", p(&out)]).stderr).unwrap();
    assert!(e.contains("cut.wtacc: checksum mismatch"), "{e}");
    assert!(!out.exists());
}

#[test]
fn merge_takes_spp_for_parts_that_do_not_record_it() {
    let dir = TempDir::new("nospp");
    // Partial films saved with Film::save (no AccMeta, as checkpoints of
    // builds before shards were): no spp.
    let scene = Scene::cornell();
    let mut settings = common::settings(&scene, 8, 8, 8);
    settings.threads = 1;
    let renderer = Renderer::new(&scene, &settings).unwrap();
    let hash = settings.image_hash(&scene);
    let parts: Vec<PathBuf> = [0..3, 3..8]
        .into_iter()
        .enumerate()
        .map(|(k, range)| {
            let mut film = renderer.new_film();
            renderer.render_samples(range, &mut film);
            let path = dir.join(format!("ckpt-{k}.wtacc"));
            film.save(&path, hash).unwrap();
            path
        })
        .collect();
    let out = dir.join("out.wtacc");
    let e = String::from_utf8(merge(&dir, &parts, &["--out", p(&out)]).stderr).unwrap();
    assert!(e.contains("pass --spp N"), "{e}");
    let e =
        String::from_utf8(merge(&dir, &parts, &["--out", p(&out), "--spp", "9"]).stderr).unwrap();
    assert!(e.contains("missing samples 8..9 of 0..9"), "{e}");
    let e =
        String::from_utf8(merge(&dir, &parts, &["--out", p(&out), "--spp", "7"]).stderr).unwrap();
    assert!(
        e.contains("ckpt-1.wtacc: holds samples up to 8, beyond --spp 7"),
        "{e}"
    );
    ok(merge(&dir, &parts, &["--out", p(&out), "--spp", "8"]));
    let (merged, meta) = Film::load_with_meta(&out, Some(hash)).unwrap();
    assert_eq!(merged, renderer.render().0);
    assert_eq!(meta.spp, Some(8));
}

/// The container command of a Kubernetes Job manifest (`args: - >-`, a
/// folded scalar: its lines joined by spaces), with Kubernetes' own
/// expansion of `$$` to `$`, and the Job's `completions`.
fn k8s_job_command(manifest: &str) -> (String, u32) {
    let lines: Vec<&str> = manifest.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    let start = (lines.iter())
        .position(|l| l.trim() == "- >-")
        .expect("a folded args scalar");
    let command: Vec<&str> = lines[start + 1..]
        .iter()
        .take_while(|l| indent(l) > indent(lines[start]))
        .map(|l| l.trim())
        .collect();
    let completions = (lines.iter())
        .find_map(|l| l.trim().strip_prefix("completions:"))
        .and_then(|v| v.split('#').next()?.trim().parse().ok())
        .expect("completions: N");
    (command.join(" ").replace("$$", "$"), completions)
}

/// farm/k8s/views.yaml's pods, run here as its Indexed Job would run them
/// (pod i with JOB_COMPLETION_INDEX=i, the shared volume a folder, a small
/// job file on it): together they write exactly the files of one
/// uninterrupted run, and a retried pod renders nothing again.
#[test]
fn the_kubernetes_views_example_runs_as_an_indexed_job() {
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("farm/k8s/views.yaml"))
            .unwrap();
    let (command, completions) = k8s_job_command(&manifest);
    assert!(
        command.contains(&format!("--shard-count {completions}")),
        "the shard count is the Job's completions: {command}"
    );
    assert!(manifest.contains("mountPath: /data"), "{manifest}");
    let dir = TempDir::new("k8s-views");
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let glb = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured.glb");
    for name in ["a.glb", "b.glb"] {
        std::fs::copy(&glb, data.join(name)).unwrap();
    }
    std::fs::write(
        data.join("job.toml"),
        "[assets]\nfiles = [\"a.glb\", \"b.glb\"]\nnormalize = true\n\n[cameras]\nkind = \"orbit\"\nviews = 5\n\n[render]\nwidth = 12\nheight = 12\nspp = 2\n\n[outputs]\ncolor = [\"png\"]\naov = [\"depth\"]\n",
    )
    .unwrap();
    // The image's PATH has wavetrace; here it is the built binary's folder.
    let bin = Path::new(env!("CARGO_BIN_EXE_wavetrace")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let command = command.replace("/data", p(&data));
    let pod = |i: u32| {
        let o = std::process::Command::new("sh")
            .args(["-c", &command])
            .env("JOB_COMPLETION_INDEX", i.to_string())
            .env("PATH", &path)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(o.status.success(), "pod {i}: {}", common::text(&o));
    };
    for i in 0..completions {
        pod(i);
    }
    run_ok(
        &dir,
        &["views", p(&data.join("job.toml")), "--out-dir", "single"],
    );
    // Every file but the per-pod stats.
    let files = |root: &Path| {
        let mut all = common::tree(root);
        all.retain(|path, _| {
            !(path.file_name()).is_some_and(|n| n.to_string_lossy().starts_with("stats-"))
        });
        all
    };
    let (pods, single) = (files(&data.join("out")), files(&dir.join("single")));
    assert_eq!(
        pods.keys().collect::<Vec<_>>(),
        single.keys().collect::<Vec<_>>()
    );
    assert!(pods == single, "the pods' files are the single run's bytes");
    assert!(pods.len() >= 2 * (2 * 5 + 2), "{} files", pods.len());
    // Every pod wrote its stats; a retried pod skips the views it finished.
    for i in 0..completions {
        assert!(
            data.join(format!("out/stats-{i}.json")).is_file(),
            "pod {i}"
        );
    }
    // (10 pairs in 16 shards: the last pod has one view; the first none.)
    let last = completions - 1;
    pod(last);
    let stats = std::fs::read_to_string(data.join(format!("out/stats-{last}.json"))).unwrap();
    let stats: serde_json::Value = serde_json::from_str(&stats).unwrap();
    assert_eq!(
        (stats["rendered"].as_u64(), stats["skipped"].as_u64()),
        (Some(0), Some(1)),
        "{stats}"
    );
    assert!(files(&data.join("out")) == pods);
}
