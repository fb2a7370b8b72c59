//! Mesh files, by extension: the one table ([`MESH_FORMATS`]) a new mesh
//! format is registered in.
//!
//! Every reader turns its file into the one intermediate form, an
//! [`Asset`] (meshes, their placements, materials, textures, cameras),
//! from which [`asset_scene`](super::asset_scene) places the meshes in a
//! scene — an asset rendered alone, or one a TOML scene places with
//! `[[asset]]`. A new format is its reader's file plus one entry here.

use super::asset::{Asset, AssetError};
use std::path::Path;

/// A mesh file format wavetrace reads.
#[derive(Debug)]
pub struct MeshFormat {
    /// What the format is called in messages.
    pub name: &'static str,
    /// File extensions, lower case, without the dot.
    pub extensions: &'static [&'static str],
    /// The reader.
    pub load: fn(&Path) -> Result<Asset, AssetError>,
    /// Whether `wavetrace FILE` renders a file of the format alone (with
    /// a camera and light of its own where it has none).
    pub renders_alone: bool,
}

/// The mesh formats, by extension.
pub const MESH_FORMATS: &[MeshFormat] = &[
    MeshFormat {
        name: "glTF 2.0",
        extensions: &["gltf", "glb"],
        load: super::gltf::load,
        renders_alone: true,
    },
    MeshFormat {
        name: "PLY",
        extensions: &["ply"],
        load: super::ply::load,
        renders_alone: true,
    },
    MeshFormat {
        name: "Wavefront OBJ",
        extensions: &["obj"],
        load: super::obj::load_asset,
        renders_alone: false,
    },
];

/// The format of the file at `path`, by its extension (any case).
pub fn format_of(path: &Path) -> Option<&'static MeshFormat> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    MESH_FORMATS
        .iter()
        .find(|f| f.extensions.contains(&ext.as_str()))
}

/// Reads the mesh file at `path` by its format; a file of no known
/// extension is refused, naming the ones read.
pub fn load(path: &Path) -> Result<Asset, AssetError> {
    match format_of(path) {
        Some(format) => (format.load)(path),
        None => {
            let known: Vec<String> = MESH_FORMATS
                .iter()
                .flat_map(|f| f.extensions)
                .map(|e| format!(".{e}"))
                .collect();
            Err(AssetError::new(
                &path.display().to_string(),
                "",
                format!(
                    "not a mesh file wavetrace reads (by its extension; known: {})",
                    known.join(", ")
                ),
            ))
        }
    }
}
