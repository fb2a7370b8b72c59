//! Files written whole or not at all, and the checks made on output paths
//! before any work starts.

use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// A file that could not be read or written, and the system's reason.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", path.display())]
pub struct FileError {
    /// The file.
    pub path: PathBuf,
    /// The operating system's reason.
    pub source: std::io::Error,
}

impl FileError {
    /// The error `source` about `path`.
    pub fn new(path: &Path, source: std::io::Error) -> Self {
        Self {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// The temporary path beside `path` that [`write_atomic`] writes first.
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map_or("out".into(), |n| n.to_string_lossy());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// What is at an output path now.
enum Target {
    /// Nothing, or a regular file: written atomically (this path, or the
    /// file a symbolic link names, so the link stays a link).
    Regular(PathBuf),
    /// Something else that can be written, such as a terminal, a pipe or
    /// `/dev/null`: written in place, never replaced.
    Special,
}

/// Where writing `path` goes, refusing a directory.
fn target(path: &Path) -> std::io::Result<Target> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a directory",
        )),
        Ok(m) if !m.is_file() => Ok(Target::Special),
        Ok(_) if path.is_symlink() => Ok(Target::Regular(std::fs::canonicalize(path)?)),
        // Absent (or a dangling link, which the rename replaces).
        _ => Ok(Target::Regular(path.to_path_buf())),
    }
}

/// Write a file atomically: everything goes to a temporary file beside it,
/// which is flushed to disk and then renamed over `path` (and the rename is
/// flushed too, where the system allows). On any error the
/// temporary file is removed and `path` is left as it was.
///
/// Only regular files are written so: an output that exists and is not
/// one (a terminal, a pipe, `/dev/stdout`, `/dev/null`) is written in
/// place, never replaced by a file; a symbolic link to a regular file is
/// kept, and the file it names replaced atomically; a directory is
/// refused.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), FileError> {
    let real = match target(path).map_err(|e| FileError::new(path, e))? {
        Target::Special => {
            return (|| {
                let file = std::fs::OpenOptions::new().write(true).open(path)?;
                let mut w = BufWriter::new(file);
                write(&mut w)?;
                w.into_inner().map_err(|e| e.into_error())?;
                Ok(())
            })()
            .map_err(|source| FileError::new(path, source));
        }
        Target::Regular(real) => real,
    };
    let tmp = temp_path(&real);
    let result = (|| {
        let mut w = BufWriter::new(std::fs::File::create(&tmp)?);
        write(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        std::fs::rename(&tmp, &real)?;
        sync_parent(&real);
        Ok(())
    })();
    result.map_err(|source| {
        let _ = std::fs::remove_file(&tmp);
        FileError::new(path, source)
    })
}

/// Flush `path`'s directory entry to disk, so a rename survives a power cut
/// or reboot (on Unix; best effort: some file systems refuse to sync a
/// directory, and the rename has happened either way).
fn sync_parent(path: &Path) {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}

/// Check, before any work starts, that `path` can be written: its directory
/// exists and a file can be created there (or, for an output that is not a
/// regular file, such as `/dev/stdout`, that it is not a directory: it is
/// written in place, see [`write_atomic`]).
pub fn check_writable(path: &Path) -> Result<(), FileError> {
    let real = match target(path).map_err(|e| FileError::new(path, e))? {
        Target::Special => return Ok(()),
        Target::Regular(real) => real,
    };
    let tmp = temp_path(&real);
    std::fs::File::create(&tmp)
        .and_then(|_| std::fs::remove_file(&tmp))
        .map_err(|source| FileError::new(path, source))
}

/// Whether two paths name the same file, whether or not it exists yet:
/// each is compared as its canonical directory plus its file name.
pub fn same_file(a: &Path, b: &Path) -> bool {
    fn normal(p: &Path) -> Option<PathBuf> {
        if let Ok(full) = std::fs::canonicalize(p) {
            return Some(full);
        }
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        Some(std::fs::canonicalize(dir).ok()?.join(p.file_name()?))
    }
    match (normal(a), normal(b)) {
        (Some(a), Some(b)) => a == b,
        _ => a == b,
    }
}

/// The memory this process can have in bytes, where it can be told: the
/// smallest of the physical memory (`MemTotal` of `/proc/meminfo`), the
/// control group's limit (`memory.max`, or `memory.limit_in_bytes` of
/// cgroup v1) and the process's address-space limit (`ulimit -v`).
/// `None` elsewhere.
pub fn system_memory() -> Option<u64> {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let total = read("/proc/meminfo").and_then(|text| {
        let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        kib.checked_mul(1024)
    });
    let cgroup = [
        "/sys/fs/cgroup/memory.max",
        "/sys/fs/cgroup/memory/memory.limit_in_bytes",
    ]
    .iter()
    .filter_map(|p| read(p)?.trim().parse::<u64>().ok())
    .min();
    [total, cgroup, address_space_limit()]
        .into_iter()
        .flatten()
        .min()
}

/// This process's address-space limit (`RLIMIT_AS`, `ulimit -v`): its soft
/// value from `/proc/self/limits`, or `None` where it is unlimited or
/// cannot be read. Allocations past it fail however much memory is free.
fn address_space_limit() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = text.lines().find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}
