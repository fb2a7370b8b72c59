//! `wavetrace bench`: the shipped image hashes are the images this build
//! renders, at every suite size; the command runs, writes JSON and
//! compares it.

mod common;

use common::{TempDir, run, run_ok, stdout};
use wavetrace::run::bench::{EXPECTED_HASHES, SuiteSize, render_workload, workloads};

/// Every workload at every size renders the image whose hash is shipped
/// (the full suite too: about 15 s on 2 cores). On failure, prints the
/// table to paste into `EXPECTED_HASHES` (src/run/bench.rs).
#[test]
fn shipped_hashes_are_the_images_rendered() {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut table = String::new();
    let mut wrong = Vec::new();
    for w0 in workloads(SuiteSize::Full) {
        for size in [SuiteSize::Full, SuiteSize::Quick, SuiteSize::Tiny] {
            let w = workloads(size)
                .into_iter()
                .find(|w| w.name == w0.name)
                .unwrap();
            let prepared = w.prepare().unwrap();
            let hash = render_workload(&w, &prepared, threads).unwrap().hash;
            table += &format!("    ({:?}, SuiteSize::{size:?}, {hash:?}),\n", w.name);
            if w.expected_hash(size) != Some(hash.as_str()) {
                wrong.push(format!(
                    "{} {size:?}: rendered {hash}, shipped {:?}",
                    w.name,
                    w.expected_hash(size)
                ));
            }
        }
    }
    assert_eq!(EXPECTED_HASHES.len(), 12, "one hash per workload and size");
    assert!(
        wrong.is_empty(),
        "the shipped bench hashes are not what this build renders:\n{}\n\
         If the images changed on purpose, replace EXPECTED_HASHES in src/run/bench.rs with:\n{table}",
        wrong.join("\n")
    );
}

/// Threads never change the image: 1 thread gives the shipped hash too.
#[test]
fn one_thread_gives_the_same_hashes() {
    for w in workloads(SuiteSize::Tiny) {
        let hash = render_workload(&w, &w.prepare().unwrap(), 1).unwrap().hash;
        assert_eq!(
            Some(hash.as_str()),
            w.expected_hash(SuiteSize::Tiny),
            "{}",
            w.name
        );
    }
}

#[test]
fn bench_json_and_compare() {
    let dir = TempDir::new("bench");
    let o = run_ok(
        dir.path(),
        &[
            "bench",
            "--tiny",
            "--repeats",
            "2",
            "--threads",
            "1,2",
            "--json",
            "a.json",
        ],
    );
    let out = stdout(&o);
    assert!(out.contains("VERIFIED: every image matches"), "{out}");
    assert!(!out.contains("MISMATCH"), "{out}");
    for w in [
        "cornell-report",
        "cornell-default",
        "sphere-1m",
        "asset-views",
    ] {
        assert!(out.contains(w), "{out}");
    }
    assert!(out.contains("single thread"), "{out}");
    // Where the time goes: each workload's stage shares add up to 1.
    assert!(out.contains("where the time goes"), "{out}");
    assert!(out.contains("asset-views      generate"), "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("a.json")).unwrap()).unwrap();
    assert_eq!(json["verified"], true);
    assert_eq!(json["size"], "tiny");
    assert_eq!(json["workloads"].as_array().unwrap().len(), 4);
    assert_eq!(json["workloads"][3]["images"], 12);
    assert!(out.contains("12 images 32x32"), "{out}");
    assert!(out.contains("images/hour on 2 thread(s)"), "{out}");
    let runs = json["workloads"][0]["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    assert_eq!(runs[0]["seconds"].as_array().unwrap().len(), 2);
    assert!(runs[1]["efficiency"].as_f64().unwrap() > 0.0);
    for w in json["workloads"].as_array().unwrap() {
        let shares = w["runs"][1]["stages"].as_object().unwrap();
        let sum: f64 = shares.values().map(|x| x.as_f64().unwrap()).sum();
        assert!(shares.len() == 8 && (sum - 1.0).abs() < 1e-9, "{w}");
    }
    // The textured asset's texture lookups: a share of those stages.
    let textures = json["workloads"][3]["runs"][1]["texture_share"]
        .as_f64()
        .unwrap();
    assert!(textures > 0.0 && textures < 1.0, "{textures}");
    assert_eq!(json["workloads"][0]["runs"][1]["texture_share"], 0.0);
    assert!(out.contains("% of it)"), "{out}");
    assert!(json["machine"]["cores"].as_u64().unwrap() >= 1);
    assert!(!json["build"]["version"].as_str().unwrap().is_empty());
    assert!(json["scores"]["single_thread_mpaths"].as_f64().unwrap() > 0.0);

    run_ok(
        dir.path(),
        &[
            "bench",
            "--tiny",
            "--repeats",
            "1",
            "--threads",
            "1",
            "--json",
            "b.json",
        ],
    );
    let o = run_ok(dir.path(), &["bench", "--compare", "a.json", "b.json"]);
    let out = stdout(&o);
    assert!(out.contains("a.json") && out.contains("b.json"), "{out}");
    assert!(out.contains("(1.00x)"), "ratios to the first file: {out}");
    assert!(out.contains("sphere-1m 1T Mpaths/s"), "{out}");
    // Aligned: every cell right-aligned in its column, so every line of
    // the table ends at the same column; and nothing cut short.
    let lengths: Vec<usize> = out
        .lines()
        .filter(|l| !l.starts_with("warning"))
        .map(|l| l.chars().count())
        .collect();
    assert!(lengths.windows(2).all(|w| w[0] == w[1]), "{out}");
    let cpu = json["machine"]["cpu_model"].as_str().unwrap();
    let features = json["build"]["target_features"].as_array().unwrap();
    let features: Vec<&str> = features.iter().map(|f| f.as_str().unwrap()).collect();
    assert!(out.contains(cpu), "{cpu} whole in {out}");
    assert!(out.contains(&features.join(" ")), "{out}");
    assert!(out.contains("other processes' CPU"), "{out}");
}

/// `bench` measures the CPU time other processes take during its runs
/// and says BUSY beside a figure and a score taken on a busy machine.
#[test]
fn bench_says_busy_when_other_processes_use_the_cpu() {
    let dir = TempDir::new("busy");
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    /// Busy loops, one a core, killed (each by its own handle) when
    /// dropped, even if the test fails.
    struct Spinners(Vec<std::process::Child>);
    impl Drop for Spinners {
        fn drop(&mut self) {
            for s in &mut self.0 {
                let _ = s.kill();
                let _ = s.wait();
            }
        }
    }
    let spinners = Spinners(
        (0..cores)
            .map(|_| {
                std::process::Command::new("sh")
                    .args(["-c", "while :; do :; done"])
                    .spawn()
                    .unwrap()
            })
            .collect(),
    );
    let out = run(
        dir.path(),
        // Enough repeats of the tiny suite for the CPU time to be counted.
        &["bench", "--tiny", "--repeats", "50", "--threads", "1"],
    );
    drop(spinners);
    let text = stdout(&out);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("BUSY"), "{text}");
    let score = text.lines().find(|l| l.contains("single thread")).unwrap();
    assert!(score.contains("BUSY"), "{score}");
}
