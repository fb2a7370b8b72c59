//! Embeds the git commit wavetrace is built from as `WAVETRACE_GIT_COMMIT`
//! (`git rev-parse --short HEAD`), or "unknown" without git or a checkout.
//! An environment variable of that name, when set, wins (for packagers).

use std::path::{Path, PathBuf};
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    let text = String::from_utf8(out.stdout).ok()?.trim().to_string();
    (out.status.success() && !text.is_empty()).then_some(text)
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=WAVETRACE_GIT_COMMIT");
    if let Ok(commit) = std::env::var("WAVETRACE_GIT_COMMIT") {
        println!("cargo:rustc-env=WAVETRACE_GIT_COMMIT={commit}");
        return;
    }
    let commit = git(&["rev-parse", "--short", "HEAD"]).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=WAVETRACE_GIT_COMMIT={commit}");

    // Build again when HEAD moves: HEAD itself (a branch switch), the branch
    // it points to (a commit), and packed-refs. `--git-path` finds them in a
    // worktree too. Only existing files are named: cargo would rebuild every
    // time for a missing one.
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let mut watch = vec!["HEAD".to_string(), "packed-refs".to_string()];
    if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
        watch.push(branch);
    }
    for name in watch {
        if let Some(p) = git(&["rev-parse", "--git-path", &name]) {
            let p = root.join(Path::new(&p));
            if p.exists() {
                println!("cargo:rerun-if-changed={}", p.display());
            }
        }
    }
}
