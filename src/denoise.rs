//! Denoising with Intel Open Image Denoise (OIDN 2.x, CPU device), loaded
//! at run time: wavetrace neither links nor builds against it, so a plain
//! build and its tests need nothing extra.
//!
//! The library (`libOpenImageDenoise.so.2`) is looked for, in order:
//! 1. the file named by the environment variable `OIDN_LIB`, or the folder
//!    named by `OIDN_DIR` (the library in it, or in its `lib` folder);
//! 2. the `oidn/lib` folder of an installed `pyoidn` Python wheel
//!    (`pip install pyoidn`), found with `python3`;
//! 3. the system's loader (`LD_LIBRARY_PATH`, `ldconfig`).
//!
//! [`Denoiser::denoise`] runs OIDN's `RT` filter on linear HDR colour; with
//! albedo and normal buffers ([`Aux`]), it first filters those (as OIDN
//! recommends for noisy auxiliaries, which Monte Carlo ones are) and then
//! the colour with `cleanAux`.

use std::ffi::{CStr, CString, c_char, c_void};
use std::path::{Path, PathBuf};

/// The library's file name (OIDN 2.x on Linux).
pub const LIBRARY_NAME: &str = "libOpenImageDenoise.so.2";

/// Why denoising failed.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    /// No OIDN library was found (or none would load).
    #[error(
        "Intel Open Image Denoise 2.x ({LIBRARY_NAME}) not found{tried}: install it with `pip install pyoidn` (wavetrace finds the wheel's oidn/lib folder through python3), or set OIDN_DIR to the folder that holds {LIBRARY_NAME} (or OIDN_LIB to the file)"
    )]
    NotFound {
        /// What was tried and why it failed, as `; tried: ...` (or empty).
        tried: String,
    },
    /// The library loaded but lacks a function wavetrace needs.
    #[error("{path}: not an Open Image Denoise 2.x library: {message}")]
    Symbol {
        /// The library's path.
        path: String,
        /// The loader's message.
        message: String,
    },
    /// OIDN reported an error.
    #[error("Open Image Denoise: {0}")]
    Oidn(String),
    /// The images given do not fit together.
    #[error("denoise: {0}")]
    Input(String),
}

type Device = *mut c_void;
type Filter = *mut c_void;

const DEVICE_TYPE_CPU: i32 = 1;
const FORMAT_FLOAT3: i32 = 3;
const ERROR_NONE: i32 = 0;

/// The C functions of OIDN 2.x that wavetrace uses (from `oidn.h`).
struct Api {
    new_device: unsafe extern "C" fn(i32) -> Device,
    commit_device: unsafe extern "C" fn(Device),
    release_device: unsafe extern "C" fn(Device),
    get_device_error: unsafe extern "C" fn(Device, *mut *const c_char) -> i32,
    new_filter: unsafe extern "C" fn(Device, *const c_char) -> Filter,
    #[allow(clippy::type_complexity)]
    set_shared_filter_image: unsafe extern "C" fn(
        Filter,
        *const c_char,
        *mut c_void,
        i32,
        usize,
        usize,
        usize,
        usize,
        usize,
    ),
    set_filter_bool: unsafe extern "C" fn(Filter, *const c_char, bool),
    commit_filter: unsafe extern "C" fn(Filter),
    execute_filter: unsafe extern "C" fn(Filter),
    release_filter: unsafe extern "C" fn(Filter),
}

/// Auxiliary images for the colour's denoising: linear albedo in [0, 1]
/// and unit (or zero) shading normals, of the colour's size.
#[derive(Clone, Copy, Debug)]
pub struct Aux<'a> {
    /// The albedo at the first non-specular hit.
    pub albedo: &'a [[f32; 3]],
    /// The shading normal there.
    pub normal: &'a [[f32; 3]],
}

/// A loaded OIDN library with a committed CPU device.
pub struct Denoiser {
    api: Api,
    device: Device,
    path: PathBuf,
    // Keeps the functions valid; dropped after the device is released.
    _lib: libloading::Library,
}

// SAFETY: OIDN devices are thread-safe (oidn.h: "all API calls are
// thread-safe" except concurrent use of one filter); filters are made and
// released within one call of `denoise` (&mut self).
unsafe impl Send for Denoiser {}

impl Drop for Denoiser {
    fn drop(&mut self) {
        // SAFETY: the device came from oidnNewDevice and is released once.
        unsafe { (self.api.release_device)(self.device) }
    }
}

/// Where the library may be, in search order (see the module's docs).
fn candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(file) = std::env::var_os("OIDN_LIB") {
        out.push(PathBuf::from(file));
    }
    if let Some(dir) = std::env::var_os("OIDN_DIR") {
        let dir = PathBuf::from(dir);
        out.push(dir.join(LIBRARY_NAME));
        out.push(dir.join("lib").join(LIBRARY_NAME));
    }
    if let Some(dir) = pyoidn_dir() {
        out.push(dir.join("oidn").join("lib").join(LIBRARY_NAME));
    }
    out.push(PathBuf::from(LIBRARY_NAME)); // the system's loader
    out
}

/// The folder of the installed `pyoidn` package, if `python3` finds one.
fn pyoidn_dir() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import importlib.util as u,os;s=u.find_spec('pyoidn');print(os.path.dirname(s.origin) if s and s.origin else '')",
        ])
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    let dir = text.trim();
    (out.status.success() && !dir.is_empty()).then(|| PathBuf::from(dir))
}

impl Denoiser {
    /// Load the library (searched as the module's docs say) and start a CPU
    /// device.
    pub fn new() -> Result<Self, DenoiseError> {
        let mut tried = Vec::new();
        for path in candidates() {
            // A bare name goes to the system's loader; a path must exist.
            let bare = path.components().count() == 1;
            if !bare && !path.is_file() {
                tried.push(format!("{} (no such file)", path.display()));
                continue;
            }
            // SAFETY: loading runs the library's initialisers; OIDN's are
            // ordinary C++ static initialisation.
            match unsafe { libloading::Library::new(&path) } {
                Ok(lib) => return Self::with_library(lib, path),
                Err(e) => tried.push(format!("{} ({e})", path.display())),
            }
        }
        Err(DenoiseError::NotFound {
            tried: format!("; tried: {}", tried.join(", ")),
        })
    }

    /// The library's path (as given to the loader).
    pub fn library_path(&self) -> &Path {
        &self.path
    }

    fn with_library(lib: libloading::Library, path: PathBuf) -> Result<Self, DenoiseError> {
        let symbol_error = |e: libloading::Error| DenoiseError::Symbol {
            path: path.display().to_string(),
            message: e.to_string(),
        };
        // SAFETY: the types are oidn.h's (OIDN 2.x) for these names.
        let api = unsafe {
            Api {
                new_device: *lib.get(b"oidnNewDevice\0").map_err(symbol_error)?,
                commit_device: *lib.get(b"oidnCommitDevice\0").map_err(symbol_error)?,
                release_device: *lib.get(b"oidnReleaseDevice\0").map_err(symbol_error)?,
                get_device_error: *lib.get(b"oidnGetDeviceError\0").map_err(symbol_error)?,
                new_filter: *lib.get(b"oidnNewFilter\0").map_err(symbol_error)?,
                set_shared_filter_image: *lib
                    .get(b"oidnSetSharedFilterImage\0")
                    .map_err(symbol_error)?,
                set_filter_bool: *lib.get(b"oidnSetFilterBool\0").map_err(symbol_error)?,
                commit_filter: *lib.get(b"oidnCommitFilter\0").map_err(symbol_error)?,
                execute_filter: *lib.get(b"oidnExecuteFilter\0").map_err(symbol_error)?,
                release_filter: *lib.get(b"oidnReleaseFilter\0").map_err(symbol_error)?,
            }
        };
        // SAFETY: plain C calls; a null device is checked.
        let device = unsafe { (api.new_device)(DEVICE_TYPE_CPU) };
        if device.is_null() {
            return Err(DenoiseError::Oidn(
                "cannot create a CPU device (unsupported CPU?)".into(),
            ));
        }
        let denoiser = Self {
            api,
            device,
            path,
            _lib: lib,
        };
        // SAFETY: a valid device.
        unsafe { (denoiser.api.commit_device)(denoiser.device) };
        denoiser.check()?;
        Ok(denoiser)
    }

    /// The device's first pending error, if any.
    fn check(&self) -> Result<(), DenoiseError> {
        let mut message: *const c_char = std::ptr::null();
        // SAFETY: a valid device; the message, when set, is a C string
        // valid until the next call on the device.
        let code = unsafe { (self.api.get_device_error)(self.device, &mut message) };
        if code == ERROR_NONE {
            return Ok(());
        }
        let text = if message.is_null() {
            String::new()
        } else {
            // SAFETY: see above.
            unsafe { CStr::from_ptr(message) }
                .to_string_lossy()
                .into_owned()
        };
        Err(DenoiseError::Oidn(format!("error {code}: {text}")))
    }

    /// Run the `RT` filter on `input` into `output` (both FLOAT3, of
    /// `width`×`height`), with the given extra images and boolean options.
    fn run_filter(
        &mut self,
        (width, height): (u32, u32),
        images: &[(&str, *mut c_void)],
        bools: &[(&str, bool)],
    ) -> Result<(), DenoiseError> {
        let c = |s: &str| CString::new(s).expect("no NUL in option names");
        // SAFETY: a valid device; every image pointer is to width×height
        // [f32; 3] pixels that outlive the filter (released below).
        unsafe {
            let filter = (self.api.new_filter)(self.device, c"RT".as_ptr());
            if filter.is_null() {
                self.check()?;
                return Err(DenoiseError::Oidn("cannot create the RT filter".into()));
            }
            for (name, ptr) in images {
                let name = c(name);
                (self.api.set_shared_filter_image)(
                    filter,
                    name.as_ptr(),
                    *ptr,
                    FORMAT_FLOAT3,
                    width as usize,
                    height as usize,
                    0,
                    0,
                    0,
                );
            }
            for (name, value) in bools {
                let name = c(name);
                (self.api.set_filter_bool)(filter, name.as_ptr(), *value);
            }
            (self.api.commit_filter)(filter);
            let committed = self.check();
            if committed.is_ok() {
                (self.api.execute_filter)(filter);
            }
            (self.api.release_filter)(filter);
            committed?;
            self.check()
        }
    }

    /// Denoise linear HDR `color` (row-major, `width`×`height`), with
    /// auxiliary images if given (filtered first, then used as clean).
    pub fn denoise(
        &mut self,
        width: u32,
        height: u32,
        color: &[[f32; 3]],
        aux: Option<Aux<'_>>,
    ) -> Result<Vec<[f32; 3]>, DenoiseError> {
        let n = width as usize * height as usize;
        if n == 0 {
            return Err(DenoiseError::Input("the image is empty".into()));
        }
        let sizes_fit =
            color.len() == n && aux.is_none_or(|a| a.albedo.len() == n && a.normal.len() == n);
        if !sizes_fit {
            return Err(DenoiseError::Input(format!(
                "the colour and auxiliary images are not all {width}x{height}"
            )));
        }
        let ptr = |v: &mut Vec<[f32; 3]>| v.as_mut_ptr().cast::<c_void>();
        // OIDN's shared images are read through mutable pointers; inputs
        // are copied so nothing the caller lent is written.
        let mut color = color.to_vec();
        let mut out = vec![[0.0f32; 3]; n];
        let size = (width, height);
        match aux {
            None => self.run_filter(
                size,
                &[("color", ptr(&mut color)), ("output", ptr(&mut out))],
                &[("hdr", true)],
            )?,
            Some(a) => {
                let mut albedo = a.albedo.to_vec();
                let mut normal = a.normal.to_vec();
                let mut clean_albedo = vec![[0.0f32; 3]; n];
                let mut clean_normal = vec![[0.0f32; 3]; n];
                self.run_filter(
                    size,
                    &[
                        ("albedo", ptr(&mut albedo)),
                        ("output", ptr(&mut clean_albedo)),
                    ],
                    &[],
                )?;
                self.run_filter(
                    size,
                    &[
                        ("normal", ptr(&mut normal)),
                        ("output", ptr(&mut clean_normal)),
                    ],
                    &[],
                )?;
                self.run_filter(
                    size,
                    &[
                        ("color", ptr(&mut color)),
                        ("albedo", ptr(&mut clean_albedo)),
                        ("normal", ptr(&mut clean_normal)),
                        ("output", ptr(&mut out)),
                    ],
                    &[("hdr", true), ("cleanAux", true)],
                )?;
            }
        }
        Ok(out)
    }
}
