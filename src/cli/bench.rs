//! `wavetrace bench`: run the verified benchmark suite, print its table,
//! write it as JSON; or compare the JSON of several machines.

use crate::error::{Error, Result};
use crate::fs::{check_writable, write_atomic};
use crate::run::bench::{
    BenchObserver, BenchReport, SuiteSize, ThreadResult, default_thread_counts, run_suite,
};
use clap::Args;
use indicatif::{ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// Options of `wavetrace bench`.
#[derive(Debug, Default, Args)]
pub struct BenchArgs {
    /// The short suite: about 10 s on 2 cores (the default suite takes
    /// about a minute).
    #[arg(long)]
    pub quick: bool,
    /// A suite of tiny renders, for testing the command itself.
    #[arg(long, hide = true, conflicts_with = "quick")]
    pub tiny: bool,
    /// Thread counts to run, comma-separated [default: 1, the powers of
    /// two below the core count, and the core count].
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub threads: Option<Vec<usize>>,
    /// Timed renders per workload and thread count (the median is
    /// reported), 1 to 1000.
    #[arg(long, default_value_t = 3, value_name = "N", value_parser = repeats)]
    pub repeats: usize,
    /// Write the machine, the build and every figure as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Compare the JSON files of earlier runs (side by side, with ratios
    /// to the first) instead of running the suite.
    #[arg(long, value_name = "FILE", num_args = 1.., conflicts_with_all = ["quick", "tiny", "threads", "json"])]
    pub compare: Option<Vec<PathBuf>>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// A bar across the whole suite on stderr, or nothing.
struct Bar(indicatif::ProgressBar);

impl BenchObserver for Bar {
    fn start(&mut self, total: u64) {
        let style = ProgressStyle::with_template(
            "{elapsed_precise} [{wide_bar}] {percent:>3}%  ETA {eta}  {msg}",
        )
        .expect("the progress template is valid")
        .progress_chars("=> ");
        self.0.set_style(style);
        self.0.set_length(total);
        self.0.enable_steady_tick(Duration::from_millis(250));
    }
    fn progress(&mut self, done: u64, what: &str) {
        self.0.set_position(done);
        self.0.set_message(what.to_string());
    }
    fn finish(&mut self) {
        self.0.finish_and_clear();
    }
}

/// Run `wavetrace bench`. Exit status 1 when an image did not match its
/// shipped hash.
pub fn run(args: BenchArgs) -> Result<ExitCode> {
    if let Some(files) = &args.compare {
        return compare(files).map(|()| ExitCode::SUCCESS);
    }
    let size = if args.tiny {
        SuiteSize::Tiny
    } else if args.quick {
        SuiteSize::Quick
    } else {
        SuiteSize::Full
    };
    if let Some(json) = &args.json {
        // The only file written; none is read (the scenes are built in,
        // and --compare, which reads, writes nothing).
        check_writable(json)?;
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = args
        .threads
        .clone()
        .unwrap_or_else(|| default_thread_counts(cores));
    let show = !args.quiet && std::io::stderr().is_terminal();
    let mut bar = Bar(if show {
        indicatif::ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
    } else {
        indicatif::ProgressBar::hidden()
    });
    let report = run_suite(size, &threads, args.repeats, &mut bar)?;
    print!("{}", table(&report));
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report).expect("the report serialises");
        write_atomic(path, |w| w.write_all(text.as_bytes()))?;
        println!("figures written to {}", path.display());
    }
    if report.verified {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "error: MISMATCH: an image differs from the one this build must render; \
             its scores are not valid (see the table)"
        );
        Ok(ExitCode::FAILURE)
    }
}

/// What other processes used of the CPU during a thread count's runs:
/// `BUSY 23%` above the threshold, else the share, or `-` unknown.
fn others(t: &ThreadResult) -> String {
    match t.others_cpu {
        Some(share) if t.busy() => format!("BUSY {:.0}%", share * 100.0),
        Some(share) => format!("{:.0}%", share * 100.0),
        None => "-".into(),
    }
}

fn gib(bytes: u64) -> String {
    format!("{:.1} GiB", bytes as f64 / (1u64 << 30) as f64)
}

/// Where each workload's rendering time went at its largest thread
/// count: the wavefront stages' shares, in the engine's order.
fn stages_table(r: &BenchReport) -> String {
    let mut s = String::new();
    for w in &r.workloads {
        let Some(t) = w.runs.last().filter(|t| !t.stages.is_empty()) else {
            continue;
        };
        if s.is_empty() {
            s += "\nwhere the time goes (wavefront stages, share of their time, at the largest thread count):\n";
        }
        let shares: Vec<String> = (crate::integrator::Stage::ALL.iter())
            .filter_map(|stage| {
                let x = t.stages.get(stage.name())?;
                Some(format!("{} {:.0}%", stage.name(), x * 100.0))
            })
            .collect();
        let textures = if t.texture_share > 0.0 {
            format!("  (textures {:.0}% of it)", t.texture_share * 100.0)
        } else {
            String::new()
        };
        s += &format!("{:<16} {}{textures}\n", w.name, shares.join("  "));
    }
    s
}

/// The report as the table printed on stdout.
pub fn table(r: &BenchReport) -> String {
    let m = &r.machine;
    let b = &r.build;
    let mut s = format!(
        "wavetrace bench: suite {} ({}), {} repeat(s)\n\
         machine: {}, {} cores, {}, {} memory, {}\n\
         build:   wavetrace {} ({}), {} with {}\n\n",
        r.suite_version,
        r.size.name(),
        r.repeats,
        m.cpu_model,
        m.cores,
        m.cpu_simd.join(" "),
        gib(m.memory_bytes),
        m.os,
        b.version,
        b.git_commit,
        b.arch,
        b.target_features.join(" "),
    );
    s += &format!(
        "{:<16} {:>7} {:>9} {:>7} {:>9} {:>9} {:>8} {:>10}  {}\n",
        "workload",
        "threads",
        "median s",
        "spread",
        "Mpaths/s",
        "Mrays/s",
        "speed-up",
        "efficiency",
        "others' CPU"
    );
    for w in &r.workloads {
        for (i, t) in w.runs.iter().enumerate() {
            s += &format!(
                "{:<16} {:>7} {:>9.3} {:>6.1}% {:>9.3} {:>9.3} {:>8} {:>10}  {}\n",
                if i == 0 { w.name.as_str() } else { "" },
                t.threads,
                t.median_seconds,
                t.spread * 100.0,
                t.mpaths_per_s,
                t.mrays_per_s,
                t.speedup.map_or("-".into(), |x| format!("{x:.2}x")),
                t.efficiency
                    .map_or("-".into(), |x| format!("{:.0}%", x * 100.0)),
                others(t),
            );
        }
    }
    s += "\n";
    for w in &r.workloads {
        let got = w.hashes.join(", ");
        if w.verified {
            // A views job makes many images; say how many an hour.
            let (images, per_hour) = match (w.images, w.runs.last()) {
                (n @ 2.., Some(t)) => (
                    format!("{n} images"),
                    format!(
                        ", {:.0} images/hour on {} thread(s)",
                        f64::from(n) * 3600.0 / t.median_seconds,
                        t.threads
                    ),
                ),
                _ => ("image".into(), String::new()),
            };
            s += &format!(
                "{:<16} VERIFIED  {images} {}x{}, {} spp, depth {}, {} / {}, {} triangles{per_hour}: hash {got}\n",
                w.name, w.width, w.height, w.spp, w.max_depth, w.integrator, w.sampler, w.triangles
            );
        } else {
            s += &format!(
                "{:<16} !!! MISMATCH !!!  image hash {got}, expected {} — wrong images: a \
                 miscompiled build, unstable hardware, or rendering code changed since the \
                 hashes were shipped\n",
                w.name,
                w.expected_hash.as_deref().unwrap_or("(none shipped)")
            );
        }
    }
    s += &stages_table(r);
    let sc = &r.scores;
    // BUSY beside a score when a run it is made of was timed while other
    // processes used the CPU.
    let busy = |one: bool| {
        let any = r.workloads.iter().any(|w| {
            let run = if one {
                w.runs.iter().find(|t| t.threads == 1)
            } else {
                w.runs.last()
            };
            run.is_some_and(|t| t.busy())
        });
        if any {
            "  BUSY: other processes used the CPU; not a clean score"
        } else {
            ""
        }
    };
    s += "\nscore (geometric mean over the workloads):\n";
    if let (Some(p), Some(q)) = (sc.single_thread_mpaths, sc.single_thread_mrays) {
        s += &format!(
            "  single thread   {p:>8.3} Mpaths/s  {q:>8.3} Mrays/s{}\n",
            busy(true)
        );
    }
    s += &format!(
        "  {:<3} thread(s)   {:>8.3} Mpaths/s  {:>8.3} Mrays/s",
        sc.all_threads, sc.all_threads_mpaths, sc.all_threads_mrays
    );
    if let Some(e) = sc.efficiency {
        s += &format!("  (scaling efficiency {:.0}%)", e * 100.0);
    }
    s += busy(false);
    s += &format!(
        "\n{}  ({:.1} s in all)\n",
        if r.verified {
            "VERIFIED: every image matches the shipped hashes"
        } else {
            "!!! MISMATCH: scores NOT valid !!!"
        },
        r.wall_seconds
    );
    s
}

/// Read reports and print them side by side.
fn compare(files: &[PathBuf]) -> Result<()> {
    let mut reports = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f)
            .map_err(|e| Error::Settings(format!("{}: cannot read: {e}", f.display())))?;
        let r: BenchReport = serde_json::from_str(&text).map_err(|e| {
            Error::Settings(format!(
                "{}: not a `wavetrace bench --json` file: {e}",
                f.display()
            ))
        })?;
        reports.push(r);
    }
    print!("{}", compare_table(files, &reports));
    Ok(())
}

/// The side-by-side table of `reports` (read from `files`).
pub fn compare_table(files: &[PathBuf], reports: &[BenchReport]) -> String {
    // Rows first; then each column as wide as its widest cell, nothing
    // cut.
    let mut rows: Vec<(String, Vec<String>)> = Vec::new();
    let mut row = |label: &str, cells: Vec<String>| rows.push((label.into(), cells));
    row("", files.iter().map(|f| f.display().to_string()).collect());
    row(
        "cpu",
        reports
            .iter()
            .map(|r| r.machine.cpu_model.clone())
            .collect(),
    );
    row(
        "cores",
        reports
            .iter()
            .map(|r| r.machine.cores.to_string())
            .collect(),
    );
    row(
        "memory",
        reports
            .iter()
            .map(|r| gib(r.machine.memory_bytes))
            .collect(),
    );
    row("os", reports.iter().map(|r| r.machine.os.clone()).collect());
    row(
        "build",
        reports
            .iter()
            .map(|r| format!("{} ({})", r.build.version, r.build.git_commit))
            .collect(),
    );
    row(
        "target features",
        reports
            .iter()
            .map(|r| r.build.target_features.join(" "))
            .collect(),
    );
    row(
        "suite",
        reports
            .iter()
            .map(|r| format!("{} ({})", r.suite_version, r.size.name()))
            .collect(),
    );
    row(
        "images",
        reports
            .iter()
            .map(|r| if r.verified { "VERIFIED" } else { "MISMATCH" }.into())
            .collect(),
    );
    // Mpaths/s, with the ratio to the first file's.
    let ratio = |v: Option<f64>, base: Option<f64>| match (v, base) {
        (Some(v), Some(b)) if b > 0.0 => format!("{v:.3} ({:.2}x)", v / b),
        (Some(v), _) => format!("{v:.3}"),
        (None, _) => "-".into(),
    };
    let first = &reports[0];
    let names: Vec<&str> = first.workloads.iter().map(|w| w.name.as_str()).collect();
    for name in names {
        let at = |r: &BenchReport, one: bool| {
            let w = r.workloads.iter().find(|w| w.name == name)?;
            let t = if one {
                w.runs.iter().find(|t| t.threads == 1)
            } else {
                w.runs.last()
            }?;
            Some(t.mpaths_per_s)
        };
        row(
            &format!("{name} 1T Mpaths/s"),
            reports
                .iter()
                .map(|r| ratio(at(r, true), at(first, true)))
                .collect(),
        );
        row(
            &format!("{name} all Mpaths/s"),
            reports
                .iter()
                .map(|r| ratio(at(r, false), at(first, false)))
                .collect(),
        );
    }
    row(
        "score 1 thread Mpaths/s",
        reports
            .iter()
            .map(|r| {
                ratio(
                    r.scores.single_thread_mpaths,
                    first.scores.single_thread_mpaths,
                )
            })
            .collect(),
    );
    row(
        "score all threads Mpaths/s",
        reports
            .iter()
            .map(|r| {
                format!(
                    "{} @{}T",
                    ratio(
                        Some(r.scores.all_threads_mpaths),
                        Some(first.scores.all_threads_mpaths)
                    ),
                    r.scores.all_threads
                )
            })
            .collect(),
    );
    row(
        "scaling efficiency",
        reports
            .iter()
            .map(|r| {
                r.scores
                    .efficiency
                    .map_or("-".into(), |e| format!("{:.0}%", e * 100.0))
            })
            .collect(),
    );
    row(
        "other processes' CPU",
        reports
            .iter()
            .map(|r| {
                let runs = r.workloads.iter().flat_map(|w| &w.runs);
                let worst = runs
                    .filter_map(|t| t.others_cpu)
                    .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))));
                match worst {
                    Some(x) if x > crate::run::bench::BUSY_SHARE => {
                        format!("BUSY (up to {:.0}%)", x * 100.0)
                    }
                    Some(x) => format!("up to {:.0}%", x * 100.0),
                    None => "-".into(),
                }
            })
            .collect(),
    );
    let width = |cell: &String| cell.chars().count();
    let label_width = rows.iter().map(|(l, _)| width(l)).max().unwrap_or(0);
    let mut widths = vec![0; reports.len()];
    for (_, cells) in &rows {
        for (w, c) in widths.iter_mut().zip(cells) {
            *w = (*w).max(width(c));
        }
    }
    let mut s = String::new();
    for (label, cells) in &rows {
        let mut line = format!("{label:<label_width$}");
        for (c, w) in cells.iter().zip(&widths) {
            line += &format!("  {c:>w$}");
        }
        s += line.trim_end();
        s += "\n";
    }
    let suites: std::collections::BTreeSet<_> = reports
        .iter()
        .map(|r| (r.suite_version, r.size.name()))
        .collect();
    if suites.len() > 1 {
        s += "warning: the files ran different suites or sizes: their scores are not comparable\n";
    }
    s
}

/// The most timed renders `--repeats` may ask for: a thousand medians'
/// worth is already hours of rendering, and the count stays far from any
/// overflow of the progress total.
pub const MAX_REPEATS: usize = 1000;

/// `--repeats`: a count from 1 to [`MAX_REPEATS`].
fn repeats(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if (1..=MAX_REPEATS).contains(&n) => Ok(n),
        _ => Err(format!(
            "must be a count from 1 to {MAX_REPEATS}, not {s:?}"
        )),
    }
}
