//! Images out — PNG, OpenEXR, PFM — written whole or not at all.

use crate::error::Error;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Image file formats, chosen by the extension of the output path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG, clamped to [0, 1].
    Png,
    /// Linear 32-bit float OpenEXR.
    Exr,
    /// Linear 32-bit float Portable Float Map.
    Pfm,
}

impl ImageFormat {
    /// The format for `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self, Error> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            Some("pfm") => Ok(Self::Pfm),
            _ => Err(Error::Settings(format!(
                "{}: unknown image format; use a .png, .exr or .pfm extension",
                path.display()
            ))),
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

/// Write a file atomically: everything goes to a temporary file beside it,
/// which is flushed to disk and then renamed over `path` (and the rename is
/// flushed too, where the system allows). On any error the
/// temporary file is removed and `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), Error> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut w = BufWriter::new(std::fs::File::create(&tmp)?);
        write(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)?;
        sync_parent(path);
        Ok(())
    })();
    result.map_err(|source| {
        let _ = std::fs::remove_file(&tmp);
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
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
/// exists and a file can be created there.
pub fn check_writable(path: &Path) -> Result<(), Error> {
    let tmp = temp_path(path);
    std::fs::File::create(&tmp)
        .and_then(|_| std::fs::remove_file(&tmp))
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
}

/// The sRGB transfer function (linear → encoded), for values in [0, 1].
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Write a linear RGB image (row-major, row 0 at the top) in the format that
/// `path`'s extension names, atomically.
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<(), Error> {
    assert_eq!(rgb.len(), width as usize * height as usize);
    match ImageFormat::from_path(path)? {
        ImageFormat::Png => {
            let bytes: Vec<u8> = rgb
                .iter()
                .flat_map(|p| p.map(|c| (srgb_encode(c.clamp(0.0, 1.0)) * 255.0).round() as u8))
                .collect();
            write_atomic(path, |w| {
                image::write_buffer_with_format(
                    w,
                    &bytes,
                    width,
                    height,
                    image::ExtendedColorType::Rgb8,
                    image::ImageFormat::Png,
                )
                .map_err(std::io::Error::other)
            })
        }
        ImageFormat::Pfm => write_atomic(path, |w| {
            write!(w, "PF\n{width} {height}\n-1.0\n")?;
            // PFM rows run bottom to top.
            for row in rgb.chunks_exact(width as usize).rev() {
                for p in row {
                    for c in p {
                        w.write_all(&c.to_le_bytes())?;
                    }
                }
            }
            Ok(())
        }),
        ImageFormat::Exr => {
            use exr::prelude::*;
            let (w_, h_) = (width as usize, height as usize);
            let image = Image::from_channels(
                (w_, h_),
                SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
                    let p = rgb[y * w_ + x];
                    (p[0], p[1], p[2])
                }),
            );
            write_atomic(path, |w| {
                let mut buf = std::io::Cursor::new(Vec::new());
                image
                    .write()
                    .to_buffered(&mut buf)
                    .map_err(std::io::Error::other)?;
                w.write_all(buf.get_ref())
            })
        }
    }
}
