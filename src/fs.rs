//! Files written whole or not at all, and the checks made on output paths
//! before any work starts.

use std::io::BufWriter;
use std::path::{Component, Path, PathBuf};

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

/// Where writing `path` goes, refusing what cannot take an output: a
/// directory, and a device other than `/dev/null` or a terminal (see
/// [`check_device`]).
fn target(path: &Path) -> std::io::Result<Target> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a directory",
        )),
        Ok(m) if !m.is_file() => {
            check_device(&m)?;
            Ok(Target::Special)
        }
        Ok(_) if path.is_symlink() => Ok(Target::Regular(std::fs::canonicalize(path)?)),
        // Absent (or a dangling link, which the rename replaces).
        _ => Ok(Target::Regular(path.to_path_buf())),
    }
}

/// Refuse an output that is a device other than `/dev/null` or a
/// terminal: a block device (a disk), or a character device such as
/// `/dev/full`, `/dev/zero` or `/dev/random`, where an image cannot be
/// written whole (and `/dev/full` fails only when written, after the
/// render). Pipes and sockets (`| gzip`, `/dev/stdout` on a pipe) are
/// streams and written in place.
#[cfg(unix)]
fn check_device(m: &std::fs::Metadata) -> std::io::Result<()> {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    let t = m.file_type();
    if t.is_fifo() || t.is_socket() {
        return Ok(());
    }
    let rdev = m.rdev();
    let major = ((rdev >> 8) & 0xfff) | ((rdev >> 32) & !0xfff);
    let minor = (rdev & 0xff) | ((rdev >> 12) & !0xff);
    // Linux's numbers: 1:3 /dev/null; 4 virtual consoles and serial
    // lines, 5 /dev/tty and /dev/console, 136-143 pseudo-terminals.
    let null_or_terminal =
        t.is_char_device() && ((major, minor) == (1, 3) || matches!(major, 4 | 5 | 136..=143));
    if null_or_terminal {
        Ok(())
    } else {
        Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "is a device ({major}:{minor}) that cannot take an output; \
                 write to a file, a pipe, a terminal or /dev/null"
            ),
        ))
    }
}

#[cfg(not(unix))]
fn check_device(_: &std::fs::Metadata) -> std::io::Result<()> {
    Ok(())
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

/// What a path names, to compare files rather than spellings: the path
/// with every link and `.`/`..` resolved (for a file that does not exist
/// yet, its nearest existing folder resolved and the rest of the path
/// applied to it, as writing it will create it), and, where it exists,
/// its device and inode (so two hard links are one file).
#[derive(Debug)]
struct Identity {
    path: PathBuf,
    inode: Option<(u64, u64)>,
    /// An existing file that is not a regular file: a pipe, a terminal,
    /// `/dev/null`. Written in place, as a stream: it never clashes.
    stream: bool,
}

impl Identity {
    fn of(p: &Path) -> Self {
        let meta = std::fs::metadata(p).ok();
        #[cfg(unix)]
        let inode = meta.as_ref().map(|m| {
            use std::os::unix::fs::MetadataExt;
            (m.dev(), m.ino())
        });
        #[cfg(not(unix))]
        let inode = None;
        Self {
            path: resolve(p),
            inode,
            stream: meta.is_some_and(|m| !m.is_file() && !m.is_dir()),
        }
    }

    fn is(&self, other: &Self) -> bool {
        if self.stream || other.stream {
            return false;
        }
        match (self.inode, other.inode) {
            (Some(a), Some(b)) => a == b,
            _ => self.path == other.path,
        }
    }
}

/// `p` absolute, with its links, `.` and `..` resolved as far as it
/// exists; the part that does not exist yet is applied lexically (it will
/// be created as plain folders and a file).
fn resolve(p: &Path) -> PathBuf {
    if let Ok(full) = std::fs::canonicalize(p) {
        return full;
    }
    let absolute = std::env::current_dir().map_or_else(|_| p.to_path_buf(), |cwd| cwd.join(p));
    let parts: Vec<Component> = absolute.components().collect();
    for n in (1..parts.len()).rev() {
        let existing: PathBuf = parts[..n].iter().collect();
        if let Ok(mut resolved) = std::fs::canonicalize(&existing) {
            for c in &parts[n..] {
                match c {
                    Component::ParentDir => {
                        resolved.pop();
                    }
                    Component::CurDir => {}
                    c => resolved.push(c),
                }
            }
            return resolved;
        }
    }
    absolute
}

/// Whether two paths name the same file, whether or not it exists yet
/// (compared as files: links resolved, hard links by inode; pipes and
/// terminals never do, see [`check_outputs`]).
pub fn same_file(a: &Path, b: &Path) -> bool {
    Identity::of(a).is(&Identity::of(b))
}

/// An output that is one of a command's inputs, or another of its outputs.
#[derive(Debug, thiserror::Error)]
pub enum Clash {
    /// The output would overwrite an input.
    #[error(
        "{}: {output} names the same file as {input} {}; an output cannot overwrite an input",
        out_path.display(),
        in_path.display()
    )]
    Input {
        /// The output's flag (`--stats`).
        output: String,
        /// Its path.
        out_path: PathBuf,
        /// The input's role (`the scene`, `--reference`).
        input: String,
        /// Its path.
        in_path: PathBuf,
    },
    /// Two outputs are one file.
    #[error(
        "{}: {first} and {second} ({}) name the same file; one would overwrite the other",
        first_path.display(),
        second_path.display()
    )]
    Outputs {
        /// One output's flag.
        first: String,
        /// Its path.
        first_path: PathBuf,
        /// The other's flag.
        second: String,
        /// Its path.
        second_path: PathBuf,
    },
}

/// Refuse, before any work and before any file is made, an output that is
/// one of the inputs or another output, compared as files ([`same_file`]:
/// the same path once links are resolved, or the same device and inode).
/// `inputs` and `outputs` are (the flag or role that names it, the path):
/// every file a command reads (the scene and every file it loads, a
/// profile, a reference, parts, a checkpoint to resume) and every file it
/// writes (the image, its AOV files, stats, partial files, checkpoints,
/// plots). Outputs that exist and are not regular files (pipes,
/// terminals, `/dev/null`) are streams, written in place: they are not
/// compared.
pub fn check_outputs(inputs: &[(&str, &Path)], outputs: &[(&str, &Path)]) -> Result<(), Clash> {
    let ins: Vec<Identity> = inputs.iter().map(|(_, p)| Identity::of(p)).collect();
    let outs: Vec<Identity> = outputs.iter().map(|(_, p)| Identity::of(p)).collect();
    for (i, o) in outs.iter().enumerate() {
        let (output, out_path) = outputs[i];
        if let Some(k) = ins.iter().position(|x| o.is(x)) {
            let (input, in_path) = inputs[k];
            return Err(Clash::Input {
                output: output.into(),
                out_path: out_path.into(),
                input: input.into(),
                in_path: in_path.into(),
            });
        }
        if let Some(k) = outs[i + 1..].iter().position(|x| o.is(x)) {
            let (second, second_path) = outputs[i + 1 + k];
            return Err(Clash::Outputs {
                first: output.into(),
                first_path: out_path.into(),
                second: second.into(),
                second_path: second_path.into(),
            });
        }
    }
    Ok(())
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
