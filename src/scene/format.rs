//! Files given as a scene that are not wavetrace scenes: other renderers'
//! and modellers' formats, meshes, images. Each is recognised by its
//! extension or its first bytes ([`FOREIGN`], the one table to edit when a
//! format becomes readable), so that `wavetrace crate.obj` says what the
//! file is and what wavetrace reads, not what the TOML parser made of it.

use std::fmt;
use std::io::Read;
use std::path::Path;

/// A file format wavetrace recognises but does not read as a scene.
#[derive(Debug)]
pub struct Foreign {
    /// What the file is, as the message names it ("a Wavefront OBJ mesh").
    pub name: &'static str,
    /// File extensions, lower case, without the dot.
    pub extensions: &'static [&'static str],
    /// Whether the file's first bytes are of this format (each test is of
    /// something no TOML scene can start with).
    pub looks_like: fn(&[u8]) -> bool,
    /// What to do instead.
    pub hint: &'static str,
}

const CONVERT: &str = "export or convert it to OBJ (Blender: File > Export > Wavefront) and place it in a scene with [[mesh]] (see scenes/README.md)";

/// Assets wavetrace renders directly, recognised by their extension
/// ([`asset_scene::is_asset`](super::asset_scene::is_asset)); a file of
/// such a format under another name is told this.
const ASSET: &str =
    "wavetrace renders .gltf, .glb and .ply files directly: give the file its extension";

/// The formats recognised, in the order they are tested.
pub const FOREIGN: &[Foreign] = &[
    Foreign {
        name: "a Wavefront OBJ mesh",
        extensions: &["obj"],
        looks_like: |head| {
            first_words(head).is_some_and(|w| {
                ["v", "vn", "vt", "f", "o", "g", "s", "mtllib", "usemtl"].contains(&w)
            })
        },
        hint: "place it in a scene with [[mesh]] file = \"...\" (see scenes/README.md; `wavetrace scenes/cornell-obj.toml` is an example)",
    },
    Foreign {
        name: "a Wavefront MTL material library",
        extensions: &["mtl"],
        looks_like: |head| first_words(head) == Some("newmtl"),
        hint: "an OBJ mesh uses it through its mtllib line: place the OBJ in a scene with [[mesh]] and mtl = true (see scenes/README.md)",
    },
    Foreign {
        name: "a PLY mesh",
        extensions: &["ply"],
        looks_like: |head| head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n"),
        hint: ASSET,
    },
    Foreign {
        name: "a glTF",
        extensions: &["gltf", "glb"],
        looks_like: |head| {
            head.starts_with(b"glTF") || (starts_text(head, "{") && contains(head, "\"asset\""))
        },
        hint: ASSET,
    },
    Foreign {
        name: "a pbrt scene",
        extensions: &["pbrt"],
        looks_like: |head| {
            first_words(head).is_some_and(|w| {
                [
                    "LookAt",
                    "Camera",
                    "Film",
                    "Sampler",
                    "Integrator",
                    "WorldBegin",
                ]
                .contains(&w)
            })
        },
        hint: CONVERT,
    },
    Foreign {
        name: "a Mitsuba scene",
        extensions: &[],
        looks_like: |head| starts_text(head, "<") && contains(head, "<scene"),
        hint: CONVERT,
    },
    Foreign {
        name: "a COLLADA",
        extensions: &["dae"],
        looks_like: |head| starts_text(head, "<") && contains(head, "<COLLADA"),
        hint: CONVERT,
    },
    Foreign {
        name: "an XML",
        extensions: &["xml"],
        looks_like: |_| false,
        hint: CONVERT,
    },
    Foreign {
        name: "a Blender",
        extensions: &["blend"],
        looks_like: |head| head.starts_with(b"BLENDER"),
        hint: "export the scene's meshes from Blender as OBJ (File > Export > Wavefront) and place them in a scene with [[mesh]] (see scenes/README.md)",
    },
    Foreign {
        name: "an FBX",
        extensions: &["fbx"],
        looks_like: |head| head.starts_with(b"Kaydara FBX Binary") || starts_text(head, "; FBX"),
        hint: CONVERT,
    },
    Foreign {
        name: "a USD",
        extensions: &["usd", "usda", "usdc", "usdz"],
        looks_like: |head| head.starts_with(b"#usda") || head.starts_with(b"PXR-USDC"),
        hint: CONVERT,
    },
    Foreign {
        name: "an STL mesh",
        extensions: &["stl"],
        looks_like: |_| false,
        hint: CONVERT,
    },
    Foreign {
        name: "an Alembic",
        extensions: &["abc"],
        looks_like: |head| contains(head, "Ogawa"),
        hint: CONVERT,
    },
    Foreign {
        name: "an image",
        extensions: &["png", "exr", "pfm", "hdr", "jpg", "jpeg", "tif", "tiff"],
        looks_like: |head| {
            head.starts_with(b"\x89PNG") || head.starts_with(&[0x76, 0x2f, 0x31, 0x01])
        },
        hint: "give it to --reference, or to `wavetrace denoise`",
    },
    Foreign {
        name: "a wavetrace partial (.wtacc)",
        extensions: &["wtacc"],
        looks_like: |head| head.starts_with(b"WTACC"),
        hint: "merge partial files with `wavetrace merge`, or continue a checkpoint with --resume",
    },
];

/// A file given as a scene that is of a format wavetrace does not read.
#[derive(Debug, thiserror::Error)]
#[error(
    "{file} is {} file; wavetrace reads TOML scenes (and the OBJ meshes they place), glTF and PLY files; {}",
    format.name,
    format.hint
)]
pub struct ForeignScene {
    /// The file, as given.
    pub file: String,
    /// What it is.
    pub format: &'static Foreign,
}

/// The foreign format of the file at `path`, by its extension or its
/// first bytes; `None` for a file that may be a TOML scene (and for one
/// that cannot be read: loading it says why).
pub fn foreign_format(path: &Path) -> Option<ForeignScene> {
    let mut head = Vec::new();
    let read = std::fs::File::open(path).and_then(|f| f.take(4096).read_to_end(&mut head));
    if read.is_err() {
        return None;
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if ext.as_deref() == Some("toml") && std::str::from_utf8(&head).is_ok() {
        return None;
    }
    let format = FOREIGN.iter().find(|f| (f.looks_like)(&head)).or_else(|| {
        let ext = ext.as_deref()?;
        FOREIGN.iter().find(|f| f.extensions.contains(&ext))
    })?;
    Some(ForeignScene {
        file: path.display().to_string(),
        format,
    })
}

/// The text of `head` from its first character that is not white space
/// (after a UTF-8 byte order mark).
fn text(head: &[u8]) -> &str {
    let s = match std::str::from_utf8(head) {
        Ok(s) => s,
        // A head cut inside a character: its valid part.
        Err(e) => std::str::from_utf8(&head[..e.valid_up_to()]).unwrap_or(""),
    };
    s.trim_start_matches('\u{feff}').trim_start()
}

fn starts_text(head: &[u8], prefix: &str) -> bool {
    text(head).starts_with(prefix)
}

fn contains(head: &[u8], needle: &str) -> bool {
    text(head).contains(needle)
}

/// The first word of the first line that is not blank or a `#` comment.
fn first_words(head: &[u8]) -> Option<&str> {
    text(head)
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .and_then(|l| l.split_whitespace().next())
}

impl fmt::Display for Foreign {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn detect(name: &str, bytes: &[u8]) -> Option<&'static str> {
        let dir = std::env::temp_dir().join(format!("wavetrace-format-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let found = foreign_format(&path).map(|f| f.format.name);
        std::fs::remove_file(&path).unwrap();
        found
    }

    #[test]
    fn formats_are_told_by_extension_and_by_content() {
        let obj = b"# a cube\nmtllib crate.mtl\nv 0 0 0\n";
        assert_eq!(detect("crate.obj", obj), Some("a Wavefront OBJ mesh"));
        assert_eq!(detect("crate.txt", obj), Some("a Wavefront OBJ mesh"));
        assert_eq!(
            detect("m.ply", b"ply\nformat ascii 1.0\n"),
            Some("a PLY mesh")
        );
        assert_eq!(detect("a.bin", b"glTF\x02\0\0\0"), Some("a glTF"));
        assert_eq!(
            detect("a.json", b"{ \"asset\": {\"version\": \"2.0\"} }"),
            Some("a glTF")
        );
        assert_eq!(
            detect("s.pbrt", b"LookAt 0 0 5  0 0 0  0 1 0\n"),
            Some("a pbrt scene")
        );
        assert_eq!(
            detect(
                "s.xml",
                b"<?xml version=\"1.0\"?>\n<scene version=\"3.0.0\">"
            ),
            Some("a Mitsuba scene")
        );
        assert_eq!(detect("x.xml", b"<other/>"), Some("an XML"));
        assert_eq!(detect("s.blend", b"BLENDER-v402"), Some("a Blender"));
        assert_eq!(detect("s.usda", b"#usda 1.0\n"), Some("a USD"));
        assert_eq!(detect("r.exr", &[0x76, 0x2f, 0x31, 0x01]), Some("an image"));
    }

    #[test]
    fn toml_scenes_are_not_foreign() {
        assert_eq!(detect("s.toml", b"[camera]\nposition = [0, 0, 0]\n"), None);
        // Any name: a scene need not end in .toml.
        assert_eq!(detect("scene", b"name = \"x\"\n[camera]\n"), None);
        assert_eq!(detect("scene.txt", b"# comment\n[camera]\n"), None);
        // A .toml file is read as TOML, even if it starts like an OBJ (the
        // parser then names the line).
        assert_eq!(detect("s.toml", b"v 0 0 0\n"), None);
    }

    #[test]
    fn the_message_names_the_file_and_what_wavetrace_reads() {
        let e = ForeignScene {
            file: "crate.obj".into(),
            format: &FOREIGN[0],
        };
        let shown = e.to_string();
        assert!(
            shown
                .starts_with("crate.obj is a Wavefront OBJ mesh file; wavetrace reads TOML scenes"),
            "{shown}"
        );
        assert!(shown.contains("[[mesh]]"), "{shown}");
    }
}
