//! The library's error type: every failure carries its kind and its place.

use std::path::PathBuf;

/// Anything that can stop a render, each kind with what the user needs to
/// fix it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file is unusable (names file, line and field).
    #[error("scene error: {0}")]
    Scene(#[from] crate::scene::SceneError),
    /// A setting is impossible (refused before any work starts).
    #[error("invalid setting: {0}")]
    Settings(String),
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// An accumulation (checkpoint or shard) file is unusable.
    #[error("{}: {message}", path.display())]
    Accumulation {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// Partial files that, merged, lack some samples of the render.
    #[error("merge: {0}")]
    Incomplete(crate::merge::MissingSamples),
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
