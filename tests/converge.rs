//! `wavetrace converge`: mean FLIP, the diminishing-returns point, the
//! progressive curve, and the command's files.

mod common;

use common::{TempDir, run, run_ok, stderr, stdout};
use wavetrace::metrics::{ImageErrors, mean_flip};
use wavetrace::render::{DEFAULT_SAMPLER, RenderSettings, Renderer};
use wavetrace::run::converge::{
    Crop, DEFAULT_JND, Setting, diminishing_returns, spp_levels, study,
};
use wavetrace::scene::{Integrator, SamplerKind, Scene};

fn small(scene: &Scene, spp: u32) -> RenderSettings {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.spp, s.threads) = (32, 24, spp, 2);
    s
}

#[test]
fn flip_of_identical_images_is_zero_and_grows_with_noise() {
    let scene = Scene::cornell();
    let (w, h) = (32, 24);
    let render = |spp| {
        Renderer::new(&scene, &small(&scene, spp))
            .unwrap()
            .render()
            .0
            .to_rgb()
    };
    let reference = render(256);
    assert_eq!(mean_flip(&reference, &reference, w, h), 0.0);
    let (f1, f16) = (
        mean_flip(&render(1), &reference, w, h),
        mean_flip(&render(16), &reference, w, h),
    );
    assert!(0.0 < f16 && f16 < f1 && f1 <= 1.0, "{f16} {f1}");
    // Black against white: a large, bounded difference.
    let (black, white) = (vec![[0.0f32; 3]; 64], vec![[1.0f32; 3]; 64]);
    let f = mean_flip(&black, &white, 8, 8);
    assert!(f > 0.5 && f <= 1.0, "{f}");
}

#[test]
fn diminishing_returns_of_a_synthetic_curve() {
    // Error 0.3/sqrt(N): a doubling lowers it by 0.3(1 - 1/sqrt 2)/sqrt(N),
    // below 0.005 from N = 512 on (0.0055 at 256, 0.0039 at 512).
    let curve: Vec<(u32, f64)> = spp_levels(1024)
        .into_iter()
        .map(|n| (n, 0.3 / (n as f64).sqrt()))
        .collect();
    assert_eq!(diminishing_returns(&curve, 0.005), Some(512));
    assert_eq!(diminishing_returns(&curve, 0.02), Some(32));
    assert_eq!(
        diminishing_returns(&curve, 0.001),
        None,
        "not reached by 1024"
    );
    // An early flat step does not count when later doublings still pay.
    let bumpy = [
        (1, 0.5),
        (2, 0.499),
        (4, 0.3),
        (8, 0.2),
        (16, 0.198),
        (32, 0.197),
    ];
    assert_eq!(diminishing_returns(&bumpy, 0.005), Some(8));
    // A last level that is not a doubling is ignored.
    let tail = [(1, 0.5), (2, 0.3), (4, 0.299), (5, 0.0)];
    assert_eq!(diminishing_returns(&tail, 0.005), Some(2));
    assert_eq!(diminishing_returns(&[(1, 0.5)], 0.005), None);
    const { assert!(DEFAULT_JND > 0.0 && DEFAULT_JND < 0.05) };
}

#[test]
fn the_progressive_curve_is_a_render_from_scratch_at_every_level() {
    let scene = Scene::cornell();
    let reference = Renderer::new(&scene, &small(&scene, 64))
        .unwrap()
        .render()
        .0
        .to_rgb();
    let base = small(&scene, 8);
    let setting = Setting {
        integrator: Integrator::Report,
        sampler: SamplerKind::Sobol,
    };
    let crop = Crop::default_for(32, 24);
    let mut samples = 0;
    let curve = study(
        &scene,
        &base,
        setting,
        &reference,
        crop,
        0.005,
        &mut |n: u32| samples += n,
    )
    .unwrap();
    assert_eq!(samples, 8);
    assert_eq!(
        curve.points.iter().map(|p| p.spp).collect::<Vec<_>>(),
        [1, 2, 4, 8]
    );
    for (p, cropped) in curve.points.iter().zip(&curve.crops) {
        let mut s = base.clone();
        (s.spp, s.integrator, s.sampler) = (p.spp, setting.integrator, setting.sampler);
        let rgb = Renderer::new(&scene, &s).unwrap().render().0.to_rgb();
        let e = ImageErrors::of(&rgb, &reference);
        assert_eq!((p.mse, p.relmse), (e.mse, e.relmse), "at {} spp", p.spp);
        assert_eq!(p.mean_flip, mean_flip(&rgb, &reference, 32, 24));
        assert_eq!(*cropped, crop.cut(&rgb, 32));
    }
    assert!(
        curve
            .points
            .windows(2)
            .all(|w| w[0].seconds <= w[1].seconds)
    );
}

#[test]
fn converge_writes_its_files() {
    let dir = TempDir::new("converge");
    let tiny = [
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "8",
        "--threads",
        "2",
    ];
    let mut args = vec!["converge", "--reference-spp", "32", "--out-dir", "out"];
    args.extend(tiny);
    args.extend([
        "--integrator",
        "report,nee",
        "--sampler",
        "independent,sobol",
    ]);
    let out = stdout(&run_ok(dir.path(), &args));
    assert!(
        out.contains("diminishing returns: report/independent"),
        "{out}"
    );
    assert!(out.contains("nee/sobol"), "{out}");
    let out_dir = dir.join("out");
    let csv = std::fs::read_to_string(out_dir.join("converge.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "integrator,sampler,spp,seconds,mse,relmse,mean_flip"
    );
    assert_eq!(lines.len(), 1 + 4 * 4, "{csv}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("converge.json")).unwrap())
            .unwrap();
    assert_eq!(json["curves"].as_array().unwrap().len(), 4);
    assert_eq!(json["reference_spp"], 32);
    assert_eq!(json["curves"][0]["points"][3]["spp"], 8);
    for png in [
        "converge-spp.png",
        "converge-time.png",
        "converge-crops.png",
    ] {
        let img = image::open(out_dir.join(png)).unwrap();
        assert!(img.width() > 100 && img.height() > 50, "{png}");
    }
    for svg in ["converge-spp.svg", "converge-time.svg"] {
        let text = std::fs::read_to_string(out_dir.join(svg)).unwrap();
        assert!(
            text.starts_with("<svg") && text.contains("mean FLIP"),
            "{svg}"
        );
    }
    assert!(out_dir.join("converge-reference.exr").exists());

    // The rendered reference serves again as --reference; one setting.
    let mut args = vec![
        "converge",
        "--reference",
        "out/converge-reference.exr",
        "--integrator",
        "nee",
        "--prefix",
        "again",
    ];
    args.extend(tiny);
    let out = stdout(&run_ok(dir.path(), &args));
    assert!(
        out.contains(&format!("nee/{}", DEFAULT_SAMPLER.name())) && !out.contains("report/"),
        "{out}"
    );
    assert!(dir.join("again.csv").exists());

    // A reference of another size is refused before any work.
    let o = run(
        dir.path(),
        &[
            "converge",
            "--reference",
            "out/converge-reference.exr",
            "--width",
            "8",
            "--prefix",
            "bad",
        ],
    );
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("the reference is 24x16"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("bad.csv").exists());
    // One of --reference and --reference-spp is needed.
    assert!(!run(dir.path(), &["converge"]).status.success());
}
