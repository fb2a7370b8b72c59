//! `wavetrace views` (issue 29): the camera files agree with the renders,
//! shards and resumes give the same bytes as one run, memory stays flat
//! over many assets, names are padded to the job's width, bad jobs are
//! refused with their place, broken assets are skipped and reported.

mod common;

use common::{TempDir, run, stderr, stdout, tree};
use glam::{Mat3, Vec3};
use std::path::{Path, PathBuf};
use wavetrace::render::Engine;
use wavetrace::run::views::{ViewsOptions, ViewsReport, name_width};
use wavetrace::scene::views_job::ViewsJob;

/// Three small emissive spheres, red, green and blue, far apart, on black.
const SPHERES: [([f32; 3], [f32; 3]); 3] = [
    ([0.7, 0.1, -0.3], [1.0, 0.0, 0.0]),
    ([-0.5, 0.4, 0.2], [0.0, 1.0, 0.0]),
    ([0.1, -0.6, 0.5], [0.0, 0.0, 1.0]),
];
const RADIUS: f32 = 0.05;

fn spheres_toml() -> String {
    let mut s = String::from(
        "[camera]\nposition = [0.0, 0.0, 5.0]\nforward = [0.0, 0.0, -1.0]\nup = [0.0, 1.0, 0.0]\nfocal_length_px = 64.0\nwidth = 64\nheight = 64\n\n[integrator]\nmax_depth = 1\n\n",
    );
    for (i, (_, c)) in SPHERES.iter().enumerate() {
        s += &format!(
            "[materials.m{i}]\nreflectance = [0.0, 0.0, 0.0]\nemission = [{:.1}, {:.1}, {:.1}]\n\n",
            4.0 * c[0],
            4.0 * c[1],
            4.0 * c[2]
        );
    }
    for (i, (p, _)) in SPHERES.iter().enumerate() {
        s += &format!(
            "[[sphere]]\nmaterial = \"m{i}\"\ncenter = [{}, {}, {}]\nradius = {RADIUS}\n\n",
            p[0], p[1], p[2]
        );
    }
    s
}

fn options(out: &Path, shard: Option<(u32, u32)>, threads: usize) -> ViewsOptions {
    ViewsOptions {
        out_dir: out.to_path_buf(),
        shard,
        threads,
        engine: Engine::Wavefront,
        batch_size: None,
        checkpoint_every: wavetrace::run::views::DEFAULT_CHECKPOINT_EVERY,
        pass_samples: None,
    }
}

fn run_job(job: &ViewsJob, o: &ViewsOptions) -> ViewsReport {
    wavetrace::run::views::run(job, o, &|| false, &mut |_| {}).unwrap()
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn f(v: &serde_json::Value) -> f32 {
    v.as_f64().unwrap() as f32
}

/// The coverage-weighted centroid of each sphere's colour in a linear
/// image (continuous pixel coordinates: pixel (i, j) covers [i, i+1) ×
/// [j, j+1)), with the weight; `None` where the sphere is not seen.
fn centroids(exr: &Path) -> Vec<Option<([f32; 2], f32)>> {
    let img = wavetrace::output::read_image(exr).unwrap();
    (0..3)
        .map(|k| {
            let (mut sum, mut wx, mut wy) = (0.0f64, 0.0f64, 0.0f64);
            for (n, p) in img.rgb.iter().enumerate() {
                let w = f64::from(p[k]);
                let (x, y) = ((n as u32 % img.width) as f64, (n as u32 / img.width) as f64);
                sum += w;
                wx += w * (x + 0.5);
                wy += w * (y + 0.5);
            }
            (sum > 0.0).then(|| ([(wx / sum) as f32, (wy / sum) as f32], sum as f32))
        })
        .collect()
}

/// Where NeRF's camera `frame` of `doc` (transforms.json) projects `x`,
/// in continuous pixel coordinates.
fn project_nerf(doc: &serde_json::Value, frame: &serde_json::Value, x: Vec3) -> [f32; 2] {
    let m = &frame["transform_matrix"];
    let at = |i: usize, j: usize| f(&m[i][j]);
    let rot = Mat3::from_cols(
        Vec3::new(at(0, 0), at(1, 0), at(2, 0)),
        Vec3::new(at(0, 1), at(1, 1), at(2, 1)),
        Vec3::new(at(0, 2), at(1, 2), at(2, 2)),
    );
    let p = Vec3::new(at(0, 3), at(1, 3), at(2, 3));
    let c = rot.transpose() * (x - p);
    let get = |k: &str| frame.get(k).map_or_else(|| f(&doc[k]), f);
    [
        get("cx") + get("fl_x") * c.x / -c.z,
        get("cy") - get("fl_y") * c.y / -c.z,
    ]
}

/// Where OpenCV's view `v` (cameras.json) projects `x`: `K (R x + t)`,
/// pixel centres at integer coordinates.
fn project_opencv(v: &serde_json::Value, x: Vec3) -> [f32; 2] {
    let r = |i: usize| Vec3::new(f(&v["R"][i][0]), f(&v["R"][i][1]), f(&v["R"][i][2]));
    let c = Vec3::new(r(0).dot(x), r(1).dot(x), r(2).dot(x))
        + Vec3::new(f(&v["t"][0]), f(&v["t"][1]), f(&v["t"][2]));
    let k = |i: usize, j: usize| f(&v["K"][i][j]);
    [k(0, 0) * c.x / c.z + k(0, 2), k(1, 1) * c.y / c.z + k(1, 2)]
}

/// Renders the spheres with `cameras` and checks that every sphere seen
/// whole lies where both camera files project its centre (within
/// `tolerance` pixels). Returns the largest error seen.
fn check_cameras(name: &str, cameras: &str, normalize: bool, extra: &[(&str, &str)]) -> f32 {
    let dir = TempDir::new(name);
    std::fs::write(dir.join("spheres.toml"), spheres_toml()).unwrap();
    for (file, text) in extra {
        std::fs::write(dir.join(file), text).unwrap();
    }
    let job_text = format!(
        "[assets]\nfiles = [\"spheres.toml\"]\nnormalize = {normalize}\n\n{cameras}\n[render]\nwidth = 64\nheight = 48\nspp = 16\nintegrator = \"bsdf\"\n\n[outputs]\ncolor = [\"exr\"]\n"
    );
    std::fs::write(dir.join("job.toml"), job_text).unwrap();
    let job = ViewsJob::load(&dir.join("job.toml")).unwrap();
    let report = run_job(&job, &options(&dir.join("out"), None, 2));
    assert_eq!(report.rendered, u64::from(job.view_count()));
    // The spheres' centres in the job's world.
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for (p, _) in SPHERES {
        lo = lo.min(Vec3::from(p) - RADIUS);
        hi = hi.max(Vec3::from(p) + RADIUS);
    }
    let world = |p: [f32; 3]| match normalize {
        true => (Vec3::from(p) - (lo + hi) * 0.5) / (hi - lo).max_element(),
        false => Vec3::from(p),
    };
    let asset = dir.join("out/spheres");
    let nerf = json(&asset.join("transforms.json"));
    let cv = json(&asset.join("cameras.json"));
    // A camera file's intrinsics come back as they were given.
    if let Some((_, text)) = extra.iter().find(|(file, _)| file.ends_with(".json")) {
        let given: serde_json::Value = serde_json::from_str(text).unwrap();
        for (i, frame) in given["frames"].as_array().unwrap().iter().enumerate() {
            for key in ["fl_x", "fl_y", "cx", "cy"] {
                if let Some(want) = frame.get(key) {
                    let out = &nerf["frames"][i];
                    let got = out.get(key).map_or_else(|| f(&nerf[key]), f);
                    assert!(
                        (got - f(want)).abs() < 1e-3,
                        "frame {i} {key}: {got} vs {want}"
                    );
                }
            }
        }
    }
    let mut worst = 0.0f32;
    let mut seen = 0;
    for (i, frame) in nerf["frames"].as_array().unwrap().iter().enumerate() {
        let file = frame["file_path"].as_str().unwrap();
        assert_eq!(cv["views"][i]["file_path"].as_str(), Some(file));
        let found = centroids(&asset.join(file));
        let scale = if normalize {
            1.0 / (hi - lo).max_element()
        } else {
            1.0
        };
        for (k, (p, _)) in SPHERES.iter().enumerate() {
            let x = world(*p);
            let a = project_nerf(&nerf, frame, x);
            let b = project_opencv(&cv["views"][i], x);
            // A sphere cut by the frame or partly hidden behind another is
            // skipped: seen whole, it covers pi fx fy (r / z)^2 pixels of 4.
            let v = &cv["views"][i];
            let z = (0..3).map(|j| f(&v["R"][2][j]) * x[j]).sum::<f32>() + f(&v["t"][2]);
            let (fx, fy) = (f(&v["K"][0][0]), f(&v["K"][1][1]));
            let expected = 4.0 * std::f32::consts::PI * fx * fy * (RADIUS * scale / z).powi(2);
            let Some((at, weight)) = found[k] else {
                continue;
            };
            if weight < 0.9 * expected {
                continue;
            }
            seen += 1;
            let e_nerf = (at[0] - a[0]).hypot(at[1] - a[1]);
            let e_cv = (at[0] - 0.5 - b[0]).hypot(at[1] - 0.5 - b[1]);
            worst = worst.max(e_nerf).max(e_cv);
            assert!(
                e_nerf < 0.25 && e_cv < 0.25,
                "{name} view {i} sphere {k}: seen at {at:?}, transforms.json says {a:?} ({e_nerf:.3} px), K R t say {b:?} (+0.5: {e_cv:.3} px)"
            );
        }
    }
    assert!(
        seen >= nerf["frames"].as_array().unwrap().len(),
        "{name}: too few spheres seen ({seen})"
    );
    worst
}

#[test]
fn camera_files_project_points_where_the_render_sees_them() {
    let orbit = check_cameras(
        "orbit",
        "[cameras]\nkind = \"orbit\"\nviews = 4\nelevations = [15.0, -40.0]\nazimuth = 10.0\n",
        true,
        &[],
    );
    let fib = check_cameras(
        "fibonacci",
        "[cameras]\nkind = \"fibonacci\"\nviews = 7\nfov = 50.0\n",
        false,
        &[],
    );
    let random = check_cameras(
        "random",
        "[cameras]\nkind = \"random\"\nviews = 6\ndistance = [2.5, 3.5]\nfov = [35.0, 55.0]\n",
        false,
        &[],
    );
    // Hand-written cameras: down -Z from +Z, down -X from +X (turned 90°
    // about +Y), from above-front, tilted 30° down, and the first again
    // with a general K (fl_x != fl_y, the principal point off the centre).
    let (s, c) = (30f32.to_radians().sin(), 30f32.to_radians().cos());
    let cams = format!(
        r#"{{"camera_angle_x": 0.9, "frames": [
  {{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3.5],[0,0,0,1]]}},
  {{"transform_matrix": [[0,0,1,3.5],[0,1,0,0.2],[-1,0,0,0],[0,0,0,1]], "fl_x": 40, "w": 64}},
  {{"transform_matrix": [[1,0,0,0],[0,{c},{s},{y}],[0,{ms},{c},{z}],[0,0,0,1]]}},
  {{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3.5],[0,0,0,1]], "fl_x": 46, "fl_y": 38, "cx": 37.5, "cy": 20.25, "w": 64, "h": 48}}
]}}"#,
        ms = -s,
        y = 3.0 * s,
        z = 3.0 * c
    );
    let explicit = check_cameras(
        "explicit",
        "[cameras]\nkind = \"explicit\"\nfile = \"cams.json\"\n",
        true,
        &[("cams.json", &cams)],
    );
    eprintln!(
        "worst errors (px): orbit {orbit:.3}, fibonacci {fib:.3}, random {random:.3}, explicit {explicit:.3}"
    );
}

/// Every file under `dir`, by relative path, with its bytes.
fn same_trees(a: &Path, b: &Path, what: &str) {
    let (ta, tb) = (tree(a), tree(b));
    assert_eq!(
        ta.keys().collect::<Vec<_>>(),
        tb.keys().collect::<Vec<_>>(),
        "{what}: other files"
    );
    for (k, v) in &ta {
        assert!(v == &tb[k], "{what}: {} differs", k.display());
    }
}

/// Two assets (the spheres scene, the shipped textured GLB), random
/// cameras and lighting, every output (the alpha, zdepth and object ids
/// with the rest).
fn two_asset_job(dir: &Path) -> ViewsJob {
    std::fs::write(dir.join("spheres.toml"), spheres_toml()).unwrap();
    let glb = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured.glb");
    std::fs::copy(glb, dir.join("textured.glb")).unwrap();
    let text = "[assets]\nfiles = [\"*.toml.asset\", \"textured.glb\"]\nlist = \"list.txt\"\nnormalize = true\n\n[cameras]\nkind = \"random\"\nviews = 5\nfov = [30.0, 50.0]\n\n[[environment]]\ncolor = [0.2, 0.3, 0.5]\n\n[[environment]]\ncolor = [1.0, 0.9, 0.7]\nstrength = 0.5\n\n[lighting]\nrandom_rotation = true\n\n[render]\nwidth = 24\nheight = 20\nspp = 4\nmax_depth = 3\nseed = 7\n\n[outputs]\ncolor = [\"png\", \"exr\"]\naov = [\"depth\", \"normal\", \"albedo\", \"zdepth\", \"object_id\", \"alpha\"]\n";
    // A glob that matches one file, and a list file naming the spheres.
    std::fs::write(dir.join("a.toml.asset"), "not an asset: a broken one").unwrap();
    std::fs::write(dir.join("list.txt"), "# the spheres\nspheres.toml\n").unwrap();
    std::fs::write(dir.join("job.toml"), text).unwrap();
    ViewsJob::load(&dir.join("job.toml")).unwrap()
}

#[test]
fn shards_and_resumes_give_the_bytes_of_one_run() {
    let dir = TempDir::new("shards");
    let job = two_asset_job(&dir);
    assert_eq!(job.assets.len(), 3);
    let one = run_job(&job, &options(&dir.join("one"), None, 2));
    assert_eq!((one.rendered, one.skipped), (10, 0));
    let failed: Vec<_> = one.failed().map(|a| a.name.clone()).collect();
    assert_eq!(
        failed,
        ["a.toml"],
        "the broken asset is reported, the rest rendered"
    );
    // Three shards, in another order, on one thread.
    for i in [2, 0, 1] {
        run_job(&job, &options(&dir.join("three"), Some((i, 3)), 1));
    }
    same_trees(&dir.join("one"), &dir.join("three"), "1 vs 3 shards");
    // Seven shards (more than some assets have views).
    let mut n = 0;
    for i in 0..7 {
        n += run_job(&job, &options(&dir.join("seven"), Some((i, 7)), 2)).rendered;
    }
    assert_eq!(n, 10, "no view rendered twice or lost");
    same_trees(&dir.join("one"), &dir.join("seven"), "1 vs 7 shards");

    // Stopped inside a view (between tiles), then between views, then run
    // again to the end.
    let out = dir.join("stopped");
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let stop = || calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst) >= 13;
    let r = wavetrace::run::views::run(&job, &options(&out, None, 1), &stop, &mut |_| {}).unwrap();
    assert!(r.stopped && r.rendered < 10, "{r:?}");
    let again = run_job(&job, &options(&out, None, 2));
    assert_eq!(again.skipped, r.rendered, "the finished views are skipped");
    assert_eq!(again.rendered + again.skipped, 10);
    same_trees(&dir.join("one"), &out, "stopped and resumed");

    // A view's file damaged (a kill mid-write of another tool, a bad disk):
    // that view alone is rendered again, to the same bytes.
    // (An AOV EXR of one view, the object-id PNG of another.)
    for damaged in ["textured/3.depth.exr", "spheres/1.object_id.png"] {
        let damaged = out.join(damaged);
        let bytes = std::fs::read(&damaged).unwrap();
        std::fs::write(&damaged, &bytes[..bytes.len() / 2]).unwrap();
    }
    let repair = run_job(&job, &options(&out, None, 2));
    assert_eq!((repair.rendered, repair.skipped), (2, 8));
    same_trees(&dir.join("one"), &out, "repaired");
}

#[test]
fn view_numbers_are_padded_to_the_job_s_width() {
    assert_eq!(
        [1, 9, 10, 12, 99, 100, 999, 1000, 9999, 10_000, 123_456].map(name_width),
        [1, 1, 2, 2, 2, 3, 3, 4, 4, 5, 6]
    );
    for (views, last, first) in [
        (1000u32, "0999.png", "0000.png"),
        (10_000, "09999.png", "00000.png"),
    ] {
        let dir = TempDir::new("padding");
        std::fs::write(dir.join("spheres.toml"), spheres_toml()).unwrap();
        std::fs::write(
            dir.join("job.toml"),
            format!("[assets]\nfiles = [\"spheres.toml\"]\n[cameras]\nkind = \"fibonacci\"\nviews = {views}\n[render]\nwidth = 2\nheight = 2\nspp = 1\n"),
        )
        .unwrap();
        let job = ViewsJob::load(&dir.join("job.toml")).unwrap();
        // The last of 500 shards: the last two views.
        let r = run_job(&job, &options(&dir.join("out"), Some((499, 500)), 1));
        assert_eq!(r.rendered, u64::from(views / 500));
        let asset = dir.join("out/spheres");
        assert!(asset.join(last).is_file(), "{last}");
        let nerf = json(&asset.join("transforms.json"));
        let frames = nerf["frames"].as_array().unwrap();
        assert_eq!(frames.len(), views as usize);
        assert_eq!(frames[0]["file_path"].as_str(), Some(first));
        assert_eq!(frames[frames.len() - 1]["file_path"].as_str(), Some(last));
    }
}

#[test]
fn bad_jobs_are_refused_naming_file_line_and_field() {
    let dir = TempDir::new("bad");
    std::fs::write(dir.join("a.glb"), b"").unwrap();
    let good_cams = "{\"camera_angle_x\": 0.8, \"frames\": [{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}";
    std::fs::write(dir.join("ok.json"), good_cams).unwrap();
    std::fs::write(
        dir.join("scaled.json"),
        "{\"camera_angle_x\": 0.8, \"frames\": [{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}, {\"transform_matrix\": [[2,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}",
    )
    .unwrap();
    std::fs::write(
        dir.join("nofov.json"),
        "{\"frames\": [{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}",
    )
    .unwrap();
    let head = "[assets]\nfiles = [\"a.glb\"]\n";
    let cases: &[(&str, &str)] = &[
        (
            "[cameras]\nkind = \"orbit\"\nviews = 0\n",
            "job.toml:5:9: field `cameras.views`",
        ),
        (
            "[cameras]\nkind = \"spiral\"\nviews = 3\n",
            "job.toml:4:8: field `cameras.kind`",
        ),
        (
            "[cameras]\nkind = \"orbit\"\nviews = 3\nelevations = [95.0]\n",
            "job.toml:6:14: field `cameras.elevations`",
        ),
        (
            "[cameras]\nkind = \"random\"\nviews = 3\ndistance = [3.0, 2.0]\n",
            "job.toml:6:12: field `cameras.distance`",
        ),
        ("[render]\nspp = 0\n", "job.toml:4:7: field `render.spp`"),
        (
            "[render]\nsamples = 4\n",
            "job.toml:4:1: field `render.samples`",
        ),
        (
            "[render]\nintegrator = \"path\"\n",
            "job.toml:4:14: field `render.integrator`",
        ),
        (
            "[outputs]\naov = [\"depth\", \"shadow\"]\n",
            "job.toml:4:7: field `outputs.aov`",
        ),
        (
            "[outputs]\ncolor = [\"jpg\"]\n",
            "job.toml:4:9: field `outputs.color`",
        ),
        (
            "[[environment]]\nstrength = -1.0\ncolor = [1.0, 1.0, 1.0]\n",
            "job.toml:4:12: field `environment[0].strength`",
        ),
        (
            "[cameras]\nkind = \"explicit\"\nfile = \"scaled.json\"\n",
            "scaled.json: field `frames[1].transform_matrix`",
        ),
        (
            "[cameras]\nkind = \"explicit\"\nfile = \"nofov.json\"\n",
            "nofov.json: field `frames[0]`",
        ),
        (
            "[cameras]\nkind = \"explicit\"\nfile = \"ok.json\"\nviews = 3\n",
            "job.toml:6:9: field `cameras.views`",
        ),
    ];
    for (i, (body, want)) in cases.iter().enumerate() {
        let job = dir.join("job.toml");
        std::fs::write(&job, format!("{head}{body}")).unwrap();
        let e = ViewsJob::load(&job).unwrap_err().to_string();
        assert!(
            e.contains(want),
            "case {i}: {e:?} does not contain {want:?}"
        );
        if i == 0 {
            // The command says it too, before any work, with status 1.
            let out = run(&dir, &["views", "job.toml", "--out-dir", "o"]);
            assert_eq!(out.status.code(), Some(1));
            assert!(stderr(&out).contains(want), "{}", stderr(&out));
            assert!(!dir.join("o").exists());
        }
    }
    let job = dir.join("job.toml");
    std::fs::write(&job, "[assets]\nfiles = [\"*.gltf\"]\n").unwrap();
    let e = ViewsJob::load(&job).unwrap_err().to_string();
    assert!(
        e.contains("job.toml:2:10: field `assets.files[0]`: no file matches"),
        "{e}"
    );
}

#[test]
fn the_command_renders_shards_skips_broken_assets_and_reports() {
    let dir = TempDir::new("cli");
    std::fs::write(dir.join("spheres.toml"), spheres_toml()).unwrap();
    std::fs::write(dir.join("broken.glb"), b"glTF garbage").unwrap();
    let args = [
        "views",
        "--asset",
        "spheres.toml",
        "--asset",
        "broken.glb",
        "--asset",
        "missing.ply",
        "--orbit",
        "3",
        "--elevation",
        "10,-20",
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "2",
        "--aov",
        "depth",
        "--out-dir",
        "o",
        "--stats",
        "s.json",
    ];
    let out = run(&dir, &args);
    assert_eq!(
        out.status.code(),
        Some(1),
        "some assets failed: {}",
        stderr(&out)
    );
    let err = stderr(&out);
    assert!(
        err.contains("failed: broken (") && err.contains("failed: missing ("),
        "{err}"
    );
    assert!(
        stdout(&out).contains("views: 6 rendered, 0 skipped"),
        "{}",
        stdout(&out)
    );
    assert!(dir.join("o/spheres/5.png").is_file() && dir.join("o/spheres/5.depth.exr").is_file());
    let stats = json(&dir.join("s.json"));
    assert_eq!(stats["rendered"], 6);
    assert_eq!(stats["failed"].as_array().unwrap().len(), 2);
    // Where the asset's time went: rays, and every wavefront stage.
    let assets = stats["assets"].as_array().unwrap();
    let asset = assets.iter().find(|a| a["error"].is_null()).unwrap();
    let paths = asset["views_rendered"].as_u64().unwrap() * 16 * 12 * 2;
    assert!(asset["rays"].as_u64().unwrap() >= paths, "{asset}");
    let stages = asset["stages"].as_object().unwrap();
    assert_eq!(stages.len(), 8, "{asset}");
    assert!(stages["intersect"].as_f64().unwrap() > 0.0, "{asset}");
    // Run again: every view is skipped. --shard auto under a Slurm array.
    let out = common::run_env(
        &dir,
        &[&args[..], &["--shard", "auto", "--shard-count", "2"]].concat(),
        &[("SLURM_ARRAY_TASK_ID", "0")],
    );
    assert!(
        stdout(&out).contains("views: 0 rendered, 6 skipped (finished earlier) of 9 (shard 0/2)"),
        "{}",
        stdout(&out)
    );
    // Flags with a job file are refused.
    std::fs::write(
        dir.join("job.toml"),
        "[assets]\nfiles = [\"spheres.toml\"]\n",
    )
    .unwrap();
    let out = run(&dir, &["views", "job.toml", "--out-dir", "o", "--spp", "4"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("--spp"), "{}", stderr(&out));
}

/// A views job of a two-object TOML scene — a quad `floor` facing +Z at
/// z = -1 over [-1, 1]², and a sphere `ball` of radius 0.5 at the origin —
/// seen from +Z by one explicit camera, normalised (so depths are scaled),
/// on a transparent background. Returns the asset's output folder and the
/// camera's position in the scene's own (unnormalised) coordinates, and
/// the normalisation's scale.
fn two_objects(dir: &Path) -> (PathBuf, Vec3, f32) {
    let scene = "[camera]\nposition = [0.0, 0.0, 5.0]\nforward = [0.0, 0.0, -1.0]\nup = [0.0, 1.0, 0.0]\nfocal_length_px = 64.0\nwidth = 8\nheight = 8\n\n[materials.grey]\nreflectance = [0.5, 0.5, 0.5]\n\n[[quad]]\nname = \"floor\"\nmaterial = \"grey\"\nvertices = [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0]]\n\n[[sphere]]\nname = \"ball\"\nmaterial = \"grey\"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.5\n";
    std::fs::write(dir.join("two.toml"), scene).unwrap();
    // The camera in the normalised world (centre (0, 0, -0.25), scale 0.5),
    // 2 units in front of it, looking down -Z, 40° across.
    let cams = r#"{"camera_angle_x": 0.6981317, "frames": [
  {"transform_matrix": [[1,0,0,0.1],[0,1,0,-0.05],[0,0,1,2],[0,0,0,1]]} ]}"#;
    std::fs::write(dir.join("cams.json"), cams).unwrap();
    let job = "[assets]\nfiles = [\"two.toml\"]\nnormalize = true\n\n[cameras]\nkind = \"explicit\"\nfile = \"cams.json\"\n\n[[environment]]\ncolor = [1.0, 1.0, 1.0]\nvisible = false\n\n[render]\nwidth = 48\nheight = 48\nspp = 16\nmax_depth = 2\n\n[outputs]\ncolor = [\"png\", \"exr\"]\naov = [\"object_id\", \"depth\", \"zdepth\", \"alpha\"]\n";
    std::fs::write(dir.join("job.toml"), job).unwrap();
    let job = ViewsJob::load(&dir.join("job.toml")).unwrap();
    let r = run_job(&job, &options(&dir.join("out"), None, 2));
    assert_eq!((r.rendered, r.failed().count()), (1, 0), "{r:?}");
    let (centre, scale) = (Vec3::new(0.0, 0.0, -0.25), 0.5);
    let eye = Vec3::new(0.1, -0.05, 2.0) / scale + centre;
    (dir.join("out/two"), eye, scale)
}

/// The unit direction, in the world (the camera looks down -Z, unturned),
/// of pixel `(x, y)`'s position `(x + dx, y + dy)` in a 48×48 view 40°
/// across.
fn pixel_ray(x: f32, y: f32) -> Vec3 {
    let f = 24.0 / (20f32.to_radians()).tan();
    Vec3::new((x - 24.0) / f, -(y - 24.0) / f, -1.0).normalize()
}

/// The distance along the unit ray `d` from `o` to the floor or the ball
/// (scene coordinates), and which (1: floor, 2: ball); `None`: a miss.
fn hit(o: Vec3, d: Vec3) -> Option<(f32, u32)> {
    // The ball: |o + t d|² = 0.25.
    let b = o.dot(d);
    let disc = b * b - (o.length_squared() - 0.25);
    if disc >= 0.0 {
        return Some((-b - disc.sqrt(), 2));
    }
    let t = (-1.0 - o.z) / d.z;
    let p = o + t * d;
    (p.x.abs() <= 1.0 && p.y.abs() <= 1.0).then_some((t, 1))
}

/// Channel `name` of a single-part EXR, and its `wavetrace` header note.
fn exr_channel(path: &Path, name: &str) -> (Vec<f32>, String) {
    use exr::prelude::{ReadChannels, ReadLayers, read};
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap();
    let layer = &image.layer_data;
    let note = match layer
        .attributes
        .other
        .get(&exr::prelude::Text::from("wavetrace"))
    {
        Some(exr::prelude::AttributeValue::Text(t)) => t.to_string(),
        _ => String::new(),
    };
    let channel = (layer.channel_data.list.iter())
        .find(|c| c.name.to_string() == name)
        .unwrap_or_else(|| panic!("{}: no channel {name}", path.display()));
    (channel.sample_data.values_as_f32().collect(), note)
}

#[test]
fn object_ids_alpha_and_depths_of_a_views_job_are_exact() {
    let dir = TempDir::new("ids");
    let (out, eye, scale) = two_objects(&dir);
    // The legend: ids in the scene's order, named by the entries' names.
    let legend = json(&out.join("objects.json"));
    assert_eq!(legend["background"], 0);
    let names: Vec<(u64, &str)> = (legend["objects"].as_array().unwrap().iter())
        .map(|o| (o["id"].as_u64().unwrap(), o["name"].as_str().unwrap()))
        .collect();
    assert_eq!(names, [(1, "floor"), (2, "ball")]);
    // The id image: 16-bit grey, the object under most of each pixel. Where
    // the whole pixel (its four corners and centre) sees one thing, that
    // thing's id, exactly; the centre, the ball's; the corners, nothing.
    let ids = image::open(out.join("0.object_id.png")).unwrap();
    assert_eq!(ids.color(), image::ColorType::L16);
    let ids = ids.into_luma16();
    let rgba = image::open(out.join("0.png")).unwrap();
    assert_eq!(rgba.color(), image::ColorType::Rgba8, "alpha in the PNG");
    let rgba = rgba.into_rgba8();
    let (depth, note) = exr_channel(&out.join("0.depth.exr"), "Z");
    assert!(note.starts_with("depth: distance from the camera centre along the ray"));
    let (zdepth, note) = exr_channel(&out.join("0.zdepth.exr"), "Z");
    assert!(note.starts_with("zdepth: distance from the camera centre along the camera's forward"));
    let (alpha, _) = exr_channel(&out.join("0.exr"), "A");
    let (mut counts, mut worst_depth, mut worst_z) = ([0; 3], 0f32, 0f32);
    for y in 0..48u32 {
        for x in 0..48u32 {
            let (fx, fy) = (x as f32, y as f32);
            let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)];
            let hits: Vec<_> = (corners.iter())
                .map(|(dx, dy)| hit(eye, pixel_ray(fx + dx, fy + dy)))
                .collect();
            let id = hits[0].map_or(0, |h| h.1);
            if hits.iter().any(|h| h.map_or(0, |h| h.1) != id) {
                continue; // an edge pixel
            }
            let k = (y * 48 + x) as usize;
            counts[id as usize] += 1;
            assert_eq!(ids.get_pixel(x, y)[0], id as u16, "id at ({x}, {y})");
            let a = rgba.get_pixel(x, y)[3];
            assert_eq!((a, alpha[k]), if id == 0 { (0, 0.0) } else { (255, 1.0) });
            if id == 0 {
                assert!(depth[k] == f32::INFINITY && zdepth[k] == f32::INFINITY);
                continue;
            }
            // The analytic depths, in the normalised world, at the pixel's
            // centre; the render's are means over the pixel, so they may
            // differ by a share of the spread over its corners.
            let d = pixel_ray(fx + 0.5, fy + 0.5);
            let t = hits[4].unwrap().0;
            let spread = (hits.iter().map(|h| h.unwrap().0).fold(f32::MIN, f32::max)
                - hits.iter().map(|h| h.unwrap().0).fold(f32::MAX, f32::min))
                * scale;
            let (want_depth, want_z) = (t * scale, t * (-d.z) * scale);
            let tol = 0.5 * spread + 1e-4;
            let (e, ez) = (depth[k] - want_depth, zdepth[k] - want_z);
            assert!(
                e.abs() <= tol && ez.abs() <= tol,
                "({x}, {y}), id {id}: depth {} want {want_depth}, zdepth {} want {want_z} (tolerance {tol})",
                depth[k],
                zdepth[k]
            );
            worst_depth = worst_depth.max(e.abs());
            worst_z = worst_z.max(ez.abs());
        }
    }
    // Most of the image is checked: background, floor and ball all seen.
    assert!(counts.iter().all(|&n| n > 100), "{counts:?}");
    eprintln!(
        "pixels checked {counts:?}; worst |depth - analytic| {worst_depth:.2e}, |zdepth - analytic| {worst_z:.2e}"
    );
    // The files all count for the view: its record hashes each.
    let record = json(&out.join("manifest/0.json"));
    let files: Vec<&String> = record["files"].as_object().unwrap().keys().collect();
    assert_eq!(
        files,
        [
            "0.depth.exr",
            "0.exr",
            "0.object_id.png",
            "0.png",
            "0.zdepth.exr"
        ]
    );
}

/// The view checkpoints (`.wtacc`) under `out`.
fn checkpoints(out: &Path) -> Vec<PathBuf> {
    let Ok(assets) = std::fs::read_dir(out) else {
        return Vec::new();
    };
    let mut found = Vec::new();
    for a in assets {
        let Ok(files) = std::fs::read_dir(a.unwrap().path().join("manifest")) else {
            continue;
        };
        for f in files {
            let p = f.unwrap().path();
            if p.extension().is_some_and(|e| e == "wtacc") {
                found.push(p);
            }
        }
    }
    found
}

#[test]
fn a_view_stopped_inside_goes_on_from_its_checkpoint() {
    let dir = TempDir::new("checkpoint");
    let job = two_asset_job(&dir);
    let one = run_job(&job, &options(&dir.join("one"), None, 2));
    assert_eq!(one.rendered, 10);
    // Passes of one sample, a checkpoint after each; stopped as soon as the
    // first view in progress has one (the deterministic hook: `stop` looks
    // for it), so inside that view, after its first pass.
    let out = dir.join("cut");
    let mut o = options(&out, None, 1);
    o.checkpoint_every = std::time::Duration::ZERO;
    o.pass_samples = Some(1);
    let stop = || !checkpoints(&out).is_empty();
    let r = wavetrace::run::views::run(&job, &o, &stop, &mut |_| {}).unwrap();
    assert!(r.stopped && r.rendered == 0, "{r:?}");
    let saved = checkpoints(&out);
    assert_eq!(saved.len(), 1, "{saved:?}");
    let (film, _) = wavetrace::film::Film::load(&saved[0], None).unwrap();
    let checkpoint = std::fs::read(&saved[0]).unwrap();
    assert_eq!(
        film.samples_per_pixel(),
        1,
        "one pass of the 4 samples saved"
    );
    // Run again: that view goes on from its checkpoint (3 more samples), the
    // rest from scratch; the files are the bytes of the uninterrupted run,
    // and no checkpoint is left.
    let again = run_job(&job, &options(&out, None, 2));
    let resumed: u32 = again.assets.iter().map(|a| a.views_resumed).sum();
    assert_eq!((again.rendered, resumed), (10, 1));
    assert!(checkpoints(&out).is_empty());
    same_trees(&dir.join("one"), &out, "resumed from a checkpoint");
    // A checkpoint of another view (or job) is not taken: a damaged or
    // foreign one is ignored, the view rendered from scratch.
    let record = out.join("spheres/manifest/2.json");
    std::fs::remove_file(&record).unwrap();
    std::fs::write(record.with_extension("wtacc"), &checkpoint).unwrap();
    let foreign = run_job(&job, &options(&out, None, 2));
    let resumed: u32 = foreign.assets.iter().map(|a| a.views_resumed).sum();
    assert_eq!((foreign.rendered, resumed), (1, 0));
    same_trees(&dir.join("one"), &out, "a foreign checkpoint ignored");
}

/// A job's `[[light]]` sun lights every view: a grey floor under a sun of
/// irradiance E at 45°, nothing else, has the radiance ρ E cos θ / π; a
/// point light is refused, naming the entry.
#[test]
fn a_job_sun_lights_the_views_as_the_closed_form_says() {
    let dir = TempDir::new("sun");
    let scene = "[camera]\nposition = [0.0, 0.0, 5.0]\nforward = [0.0, 0.0, -1.0]\nup = [0.0, 1.0, 0.0]\nfocal_length_px = 64.0\nwidth = 8\nheight = 8\n\n[materials.grey]\nreflectance = [0.5, 0.5, 0.5]\n\n[[quad]]\nname = \"floor\"\nmaterial = \"grey\"\nvertices = [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0]]\n";
    std::fs::write(dir.join("floor.toml"), scene).unwrap();
    let cams = r#"{"camera_angle_x": 0.6981317, "frames": [
  {"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,2],[0,0,0,1]]} ]}"#;
    std::fs::write(dir.join("cams.json"), cams).unwrap();
    let job = |light: &str| {
        format!(
            "[assets]\nfiles = [\"floor.toml\"]\n\n[cameras]\nkind = \"explicit\"\nfile = \"cams.json\"\n\n[[environment]]\ncolor = [0.0, 0.0, 0.0]\n\n{light}\n[render]\nwidth = 16\nheight = 16\nspp = 64\nmax_depth = 2\n\n[outputs]\ncolor = [\"exr\"]\n"
        )
    };
    let sun = "[[light]]\ntype = \"sun\"\ndirection = [0.0, -1.0, -1.0]\nirradiance = 3.0\n";
    std::fs::write(dir.join("job.toml"), job(sun)).unwrap();
    let parsed = ViewsJob::load(&dir.join("job.toml")).unwrap();
    let r = run_job(&parsed, &options(&dir.join("out"), None, 2));
    assert_eq!((r.rendered, r.failed().count()), (1, 0), "{r:?}");
    let (red, _) = exr_channel(&dir.join("out/floor/0.exr"), "R");
    // The middle 4×4 pixels see only the floor (it spans ±18° of the axis).
    let want = 0.5 * 3.0 * std::f32::consts::FRAC_1_SQRT_2 / std::f32::consts::PI;
    for y in 6..10 {
        for x in 6..10 {
            let got = red[y * 16 + x];
            assert!(
                (got - want).abs() < 0.02 * want,
                "({x}, {y}): {got} vs {want}"
            );
        }
    }
    // Only suns: a point light's place would depend on each asset.
    let point = "[[light]]\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0\n";
    let file = dir.join("job.toml").display().to_string();
    let e = ViewsJob::parse(&job(point), &file).unwrap_err().to_string();
    assert!(e.contains("light[0].type") && e.contains("suns"), "{e}");

    // The flags' `--sun X,Y,Z,IRRADIANCE` is that `[[light]]`: the same
    // bytes as the job file that writes it.
    let flagged = "[assets]\nfiles = [\"floor.toml\"]\n\n[cameras]\nkind = \"explicit\"\nfile = \"cams.json\"\n\n[[environment]]\ncolor = [0.0, 0.0, 0.0]\n\n[[light]]\ntype = \"sun\"\ndirection = [0.0, -1.0, -1.0]\nirradiance = 3.0\n\n[render]\nwidth = 16\nheight = 16\nspp = 8\nseed = 0\n";
    std::fs::write(dir.join("flagged.toml"), flagged).unwrap();
    let o = run(dir.path(), &["views", "flagged.toml", "--out-dir", "a"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let flags = [
        "views",
        "--asset",
        "floor.toml",
        "--cameras",
        "cams.json",
        "--env",
        "0,0,0",
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "8",
        "--seed",
        "0",
        "--out-dir",
        "b",
        "--sun",
    ];
    let o = run(dir.path(), &[&flags[..], &["0,-1,-1,3"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let png = |d: &str| std::fs::read(dir.join(d).join("floor/0.png")).unwrap();
    assert_eq!(png("a"), png("b"), "--sun renders as the job's [[light]]");
    let o = run(dir.path(), &[&flags[..], &["0,-1,-1,1"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(png("a"), png("b"), "the irradiance is used");
    for (bad, says) in [
        ("0,0,0,3", "direction must not be zero"),
        ("0,-1,0", "X,Y,Z,IRRADIANCE"),
        (
            "0,-1,0,-3",
            "irradiance must be a finite non-negative number",
        ),
    ] {
        let o = run(dir.path(), &[&flags[..], &[bad]].concat());
        let e = stderr(&o);
        assert!(
            !o.status.success() && e.contains("--sun") && e.contains(says),
            "{e}"
        );
    }
}
