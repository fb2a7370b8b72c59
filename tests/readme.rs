//! The README is a user document that must stay short and true: at most
//! 300 lines, its first commands the two that work on a fresh clone, no
//! commit hashes, every local link pointing at a file — and every command
//! in it works as written.
//!
//! What is run: every ```` ```sh ```` block, in order, in one fresh
//! directory that holds the clone's `scenes/` (a link), with the built
//! `wavetrace` first on `PATH` — as on a fresh clone after
//! `cargo install --path .`. Lines that start with `cargo` are not run
//! (they build and test this very crate: the first block is checked
//! instead, and the install step is what `PATH` stands for). A block
//! named by the line just above it, `` `FILE`: ``, is written to `FILE`
//! first (the "your own scene" files). Each block runs under `sh -e`.
//! The example scene error is checked to be what wavetrace prints.

mod common;

use common::{BIN, TempDir};
use std::path::Path;
use std::process::Command;

const README: &str = include_str!("../README.md");

/// A fenced block of the README: its info string, its text, and the line
/// just above its opening fence that is not blank.
struct Block<'a> {
    info: &'a str,
    text: String,
    above: &'a str,
}

fn blocks(markdown: &str) -> Vec<Block<'_>> {
    let mut out = Vec::new();
    let mut lines = markdown.lines();
    let mut above = "";
    while let Some(line) = lines.next() {
        if let Some(info) = line.strip_prefix("```") {
            let mut text = String::new();
            for l in lines.by_ref() {
                if l.starts_with("```") {
                    break;
                }
                text.push_str(l);
                text.push('\n');
            }
            out.push(Block {
                info: info.trim(),
                text,
                above,
            });
            above = "";
        } else if !line.trim().is_empty() {
            above = line.trim();
        }
    }
    out
}

/// The commands of a shell block: its lines without comments and blanks.
fn commands(text: &str) -> Vec<&str> {
    text.lines()
        .map(|l| l.split(" #").next().unwrap().trim())
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect()
}

#[test]
fn readme_is_short_and_starts_with_the_two_commands() {
    let lines = README.lines().count();
    assert!(lines <= 300, "README.md has {lines} lines: at most 300");
    let first = blocks(README)
        .into_iter()
        .next()
        .expect("README has code blocks");
    assert_eq!(first.info, "sh", "the first block is the shell commands");
    let cmds = commands(&first.text);
    assert!(
        cmds.len() == 2
            && cmds[0].starts_with("cargo run --release")
            && cmds[1].starts_with("cargo test --release"),
        "the README's first commands must be `cargo run --release` and `cargo test --release`: {cmds:?}"
    );
    // `cargo install --path .` is how `wavetrace` gets on the PATH.
    assert!(
        blocks(README)
            .iter()
            .any(|b| b.info == "sh" && commands(&b.text).contains(&"cargo install --path .")),
        "the README must say `cargo install --path .`"
    );
}

#[test]
fn readme_has_no_commit_hashes_and_its_links_resolve() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (n, line) in README.lines().enumerate() {
        for word in line.split(|c: char| !c.is_ascii_alphanumeric()) {
            let hexy = word.len() >= 7
                && word.chars().all(|c| c.is_ascii_hexdigit())
                && word.chars().any(|c| c.is_ascii_digit())
                && word.chars().any(|c| c.is_ascii_alphabetic());
            assert!(
                !hexy,
                "README.md:{}: {word:?} looks like a commit hash",
                n + 1
            );
        }
        // Markdown links and images to files of the repository.
        for part in line.split("](").skip(1) {
            let target = part.split(')').next().unwrap();
            if target.starts_with("http") || target.starts_with('#') {
                continue;
            }
            let file = target.split('#').next().unwrap();
            assert!(
                root.join(file).exists(),
                "README.md:{}: link to {file}, which does not exist",
                n + 1
            );
        }
    }
}

#[test]
fn readme_commands_work_as_written() {
    let dir = TempDir::new("readme");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::os::unix::fs::symlink(root.join("scenes"), dir.join("scenes")).unwrap();
    let bin_dir = Path::new(BIN).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut ran = 0;
    for block in blocks(README) {
        if let Some(name) = block
            .above
            .strip_prefix('`')
            .and_then(|s| s.strip_suffix("`:"))
        {
            std::fs::write(dir.join(name), &block.text).unwrap();
            continue;
        }
        if block.info != "sh" {
            continue;
        }
        let script: Vec<&str> = block
            .text
            .lines()
            .filter(|l| !l.trim_start().starts_with("cargo "))
            .collect();
        if commands(&script.join("\n")).is_empty() {
            continue;
        }
        let out = Command::new("sh")
            .arg("-ec")
            .arg(script.join("\n"))
            .current_dir(&dir)
            .env("PATH", &path)
            .env_remove("SLURM_CPUS_PER_TASK")
            .env_remove("SLURM_ARRAY_TASK_ID")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "README block failed ({}):\n{}\nstdout:\n{}\nstderr:\n{}",
            out.status,
            block.text,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        ran += 1;
    }
    assert!(ran >= 4, "only {ran} README blocks ran");
    // The example error is the one wavetrace prints for that mistake.
    let example = blocks(README)
        .into_iter()
        .find(|b| b.info == "text" && b.text.contains("my-scene.toml:"))
        .expect("the README shows a scene error");
    let scene = std::fs::read_to_string(dir.join("my-scene.toml")).unwrap();
    let good = "reflectance = [0.7, 0.7, 0.7]";
    assert!(scene.contains(good));
    std::fs::write(
        dir.join("my-scene.toml"),
        scene.replacen(good, "reflectance = \"x\"", 1),
    )
    .unwrap();
    let out = Command::new(BIN)
        .arg("my-scene.toml")
        .current_dir(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(String::from_utf8_lossy(&out.stderr), example.text);
    // What the quick start and "your own scene" promise is there.
    for file in [
        "cornell.png",
        "preview.png",
        "cornell-spheres.png",
        "my-scene.png",
        "merged.png",
    ] {
        assert!(dir.join(file).is_file(), "README commands made no {file}");
    }
}
