//! `wavetrace views` (issue 29): resident memory stays flat over many
//! assets (each loaded, built, rendered and dropped). Alone in its test
//! binary: the resident memory is the whole process's.

mod common;

use common::TempDir;
use wavetrace::render::Engine;
use wavetrace::run::views::{ViewsEvent, ViewsOptions};
use wavetrace::scene::views_job::ViewsJob;

/// Resident memory, bytes (`/proc/self/statm`).
fn resident() -> u64 {
    let text = std::fs::read_to_string("/proc/self/statm").unwrap();
    let pages: u64 = text.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}

#[test]
fn memory_stays_flat_over_hundreds_of_assets() {
    let dir = TempDir::new("memory");
    let n = 120;
    let side = 30;
    let mut list = String::new();
    for a in 0..n {
        // A wavy grid of 2·40² triangles, different for each asset.
        let mut ply = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            (side + 1) * (side + 1),
            2 * side * side
        );
        for j in 0..=side {
            for i in 0..=side {
                let (x, z) = (i as f32 / side as f32, j as f32 / side as f32);
                ply += &format!("{x} {} {z}\n", 0.1 * ((x + a as f32) * 9.0).sin() * z);
            }
        }
        for j in 0..side {
            for i in 0..side {
                let v = j * (side + 1) + i;
                ply += &format!(
                    "3 {v} {} {}\n3 {v} {} {}\n",
                    v + side + 1,
                    v + side + 2,
                    v + side + 2,
                    v + 1
                );
            }
        }
        std::fs::write(dir.join(format!("g{a:03}.ply")), ply).unwrap();
        list += &format!("g{a:03}.ply\n");
    }
    std::fs::write(dir.join("list.txt"), list).unwrap();
    std::fs::write(
        dir.join("job.toml"),
        "[assets]\nlist = \"list.txt\"\n[cameras]\nkind = \"orbit\"\nviews = 1\n[render]\nwidth = 8\nheight = 8\nspp = 1\n",
    )
    .unwrap();
    let job = ViewsJob::load(&dir.join("job.toml")).unwrap();
    let mut samples = Vec::new();
    let report = wavetrace::run::views::run(
        &job,
        &ViewsOptions {
            out_dir: dir.join("out"),
            shard: None,
            threads: 2,
            engine: Engine::Wavefront,
            batch_size: None,
            checkpoint_every: wavetrace::run::views::DEFAULT_CHECKPOINT_EVERY,
            pass_samples: None,
        },
        &|| false,
        &mut |e| {
            if let ViewsEvent::Asset(a) = e {
                assert!(a.error.is_none(), "{a:?}");
                samples.push(resident());
            }
        },
    )
    .unwrap();
    assert_eq!(report.rendered, n as u64);
    let settled = samples[n / 3];
    let last = *samples.last().unwrap();
    let most = *samples[n / 3..].iter().max().unwrap();
    eprintln!(
        "resident memory: after asset {}: {:.1} MiB, most after: {:.1} MiB, at the end: {:.1} MiB",
        n / 3,
        settled as f64 / 1048576.0,
        most as f64 / 1048576.0,
        last as f64 / 1048576.0
    );
    assert!(
        most < settled + 3 * 1048576,
        "resident memory grew from {settled} to {most} bytes over {} assets",
        n - n / 3
    );
}
