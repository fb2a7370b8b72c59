//! The library's error type: every failure carries its kind and its place.

use crate::denoise::DenoiseError;
use crate::film::WtaccError;
use crate::film::ranges::MissingSamples;
use crate::fs::{Clash, FileError};
use crate::run::shard::ShardError;
use crate::scene::SceneError;
use crate::scene::format::ForeignScene;

/// Anything that can stop a render, each kind with what the user needs to
/// fix it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file (or a mesh file it loads) is unusable: names file,
    /// line and field.
    #[error("scene error: {0}")]
    Scene(#[from] SceneError),
    /// A file given as a scene is of another format (OBJ, glTF, pbrt…):
    /// says what it is and what wavetrace reads.
    #[error(transparent)]
    ForeignScene(#[from] ForeignScene),
    /// A setting is impossible (refused before any work starts).
    #[error("invalid setting: {0}")]
    Settings(String),
    /// A shard or sample range is impossible (refused before any work
    /// starts).
    #[error("invalid setting: {0}")]
    Shard(#[from] ShardError),
    /// A file could not be read or written.
    #[error(transparent)]
    Io(#[from] FileError),
    /// An output names one of the command's inputs, or another output
    /// (refused before any work starts).
    #[error("invalid setting: {0}")]
    Clash(#[from] Clash),
    /// An accumulation file (checkpoint or partial file) is unusable.
    #[error(transparent)]
    Accumulation(#[from] WtaccError),
    /// Partial files that, merged, lack some samples of the render.
    #[error("merge: {0}")]
    Incomplete(#[from] MissingSamples),
    /// Denoising failed, or its library is missing (the message says how
    /// to install it).
    #[error(transparent)]
    Denoise(#[from] DenoiseError),
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
