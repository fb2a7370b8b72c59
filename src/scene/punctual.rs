//! Sun, point and spot lights (docs/lights.md): lights that are not
//! surfaces. A sun is a direction (or a small cone of directions, its
//! angular diameter) from infinitely far away; point and spot lights are
//! points. Those without extent (point, spot, a sun of diameter 0) are
//! *delta* lights: no ray can hit them, only next-event estimation (`nee`)
//! reaches them. The integrator's side of them is
//! `crate::integrator::punctual`.
//!
//! Units, radiometric like the rest of wavetrace:
//!
//! - a sun is given by its **irradiance** `E` (W/m², per RGB channel) on a
//!   surface facing it (Blender's sun *Strength*, glTF's directional
//!   `intensity` in lux once converted); with angular diameter `α` it is a
//!   cone of half-angle `δ = α/2` of uniform radiance
//!   `L = E / (π sin² δ)` (then `∫cone L cos θ dω = E`);
//! - a point or spot light is given by its **intensity** `I` (W/sr, per
//!   channel) along its axis; a spot's intensity falls off between its
//!   inner and outer cone angles as glTF's `KHR_lights_punctual` defines.
//!
//! In a scene file:
//!
//! ```toml
//! [[light]]
//! type = "sun"             # "sun", "point" or "spot"
//! direction = [-1, -2, -1] # where the light goes (sun, spot)
//! irradiance = 3.0         # W/m² (sun)
//! angle = 0.53             # the sun's angular diameter, degrees (default 0.53; 0: a delta)
//! color = [1, 0.9, 0.8]    # multiplies irradiance / intensity (default white)
//!
//! [[light]]
//! type = "spot"
//! position = [0, 2, 0]     # point, spot
//! direction = [0, -1, 0]
//! intensity = 10.0         # W/sr (point, spot)
//! inner_angle = 20.0       # degrees from the axis (spot; default 0)
//! outer_angle = 30.0       # degrees from the axis (spot; default 45)
//! ```

use glam::{Mat4, Vec3};
use serde::Deserialize;
use toml::Spanned;

/// The default angular diameter of a sun, degrees: the Sun's as seen from
/// the Earth.
pub const DEFAULT_SUN_ANGLE_DEG: f32 = 0.53;

/// The largest angular diameter of a sun, degrees (a hemisphere).
pub const MAX_SUN_ANGLE_DEG: f32 = 180.0;

/// glTF's default outer cone angle of a spot light, degrees (π/4).
pub const DEFAULT_OUTER_ANGLE_DEG: f32 = 45.0;

/// Lumens per watt: the luminous efficacy of light of 540 THz (555 nm),
/// which defines the candela. glTF's photometric intensities are divided
/// by it (Blender's importer's `PBR_WATTS_TO_LUMENS`).
pub const LUMENS_PER_WATT: f32 = 683.0;

/// What a light is, and where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightShape {
    /// Light from infinitely far away, travelling along `direction`
    /// (unit), from a cone of angular diameter `angle` (radians; 0: one
    /// direction, a delta light).
    Sun {
        /// Unit direction the light travels (from the sun to the scene).
        direction: Vec3,
        /// Angular diameter, radians, in `[0, π]`.
        angle: f32,
    },
    /// Light from a point, the same in every direction.
    Point {
        /// Where it is.
        position: Vec3,
    },
    /// Light from a point into a cone about `direction`: full intensity
    /// within `inner` of the axis, none beyond `outer`, glTF's smooth
    /// falloff between.
    Spot {
        /// Where it is.
        position: Vec3,
        /// Unit direction of its axis (where the light goes).
        direction: Vec3,
        /// Inner cone angle, radians from the axis, `0 ≤ inner < outer`.
        inner: f32,
        /// Outer cone angle, radians from the axis, `outer ≤ π/2`.
        outer: f32,
    },
}

/// A sun, point or spot light.
#[derive(Clone, Debug, PartialEq)]
pub struct PunctualLight {
    /// What it is, and where.
    pub shape: LightShape,
    /// Linear RGB: a sun's irradiance (W/m²) on a surface facing it; a
    /// point or spot light's intensity (W/sr) along its axis.
    pub strength: Vec3,
    /// A name for messages.
    pub name: String,
}

impl PunctualLight {
    /// Whether no ray can hit it: a point, a spot, or a sun of diameter 0
    /// (only next-event estimation reaches it).
    pub fn is_delta(&self) -> bool {
        match self.shape {
            LightShape::Sun { angle, .. } => angle == 0.0,
            _ => true,
        }
    }

    /// Whether it sends any light.
    pub fn emits(&self) -> bool {
        self.strength.max_element() > 0.0
    }

    /// The light placed by `m` (object to world): positions transformed
    /// as points, directions as vectors (renormalised).
    pub fn transformed(&self, m: Mat4) -> Self {
        let dir = |d: Vec3| m.transform_vector3(d).normalize_or(d);
        let shape = match self.shape {
            LightShape::Sun { direction, angle } => LightShape::Sun {
                direction: dir(direction),
                angle,
            },
            LightShape::Point { position } => LightShape::Point {
                position: m.transform_point3(position),
            },
            LightShape::Spot {
                position,
                direction,
                inner,
                outer,
            } => LightShape::Spot {
                position: m.transform_point3(position),
                direction: dir(direction),
                inner,
                outer,
            },
        };
        Self {
            shape,
            ..self.clone()
        }
    }

    /// Hash what changes an image.
    pub fn hash_into(&self, h: &mut xxhash_rust::xxh3::Xxh3) {
        let words: Vec<f32> = match self.shape {
            LightShape::Sun { direction, angle } => {
                vec![1.0, direction.x, direction.y, direction.z, angle]
            }
            LightShape::Point { position } => vec![2.0, position.x, position.y, position.z],
            LightShape::Spot {
                position,
                direction,
                inner,
                outer,
            } => vec![
                3.0,
                position.x,
                position.y,
                position.z,
                direction.x,
                direction.y,
                direction.z,
                inner,
                outer,
            ],
        };
        for w in words.iter().chain(&self.strength.to_array()) {
            h.update(&w.to_bits().to_le_bytes());
        }
    }
}

/// A `[[light]]` of a scene file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightFile {
    #[allow(dead_code)] // a label for people reading the file
    name: Option<String>,
    #[serde(rename = "type")]
    kind: Spanned<String>,
    color: Option<Spanned<Vec<f32>>>,
    intensity: Option<Spanned<f32>>,
    irradiance: Option<Spanned<f32>>,
    position: Option<Spanned<Vec<f32>>>,
    direction: Option<Spanned<Vec<f32>>>,
    angle: Option<Spanned<f32>>,
    inner_angle: Option<Spanned<f32>>,
    outer_angle: Option<Spanned<f32>>,
}

/// A sun written on a command line as `X,Y,Z,IRRADIANCE`: the way its
/// light goes and its irradiance (W/m²), with the default angular
/// diameter; checked as a `[[light]]` table of type `"sun"` is.
pub fn sun_from_words(text: &str) -> Result<PunctualLight, String> {
    let numbers: Option<Vec<f32>> = (text.split(','))
        .map(|w| w.trim().parse::<f32>().ok().filter(|x| x.is_finite()))
        .collect();
    let Some(&[x, y, z, e]) = numbers.as_deref() else {
        return Err(format!(
            "{text}: a sun is X,Y,Z,IRRADIANCE: four finite numbers (the way its light goes, W/m²)"
        ));
    };
    let table = format!("type = \"sun\"\ndirection = [{x:?}, {y:?}, {z:?}]\nirradiance = {e:?}\n");
    let raw: LightFile = toml::from_str(&table).map_err(|e| format!("{text}: {e}"))?;
    from_file(0, &raw).map_err(|(_, field, m)| {
        let field = field.trim_start_matches("light[0].");
        format!("{text}: its {field} {m}")
    })
}

/// Where a problem with a `[[light]]` is: the span of the scene file's
/// text, the field (`light[K].FIELD`) and the message.
pub type TableError = (std::ops::Range<usize>, String, String);

/// An error at `span` about field `field` of `[[light]]` number `k`.
fn error<T>(k: usize, span: std::ops::Range<usize>, field: &str, m: &str) -> Result<T, TableError> {
    Err((span, format!("light[{k}].{field}"), m.to_string()))
}

/// The light of the scene file's `[[light]]` number `k` (`raw`).
pub fn from_file(k: usize, raw: &LightFile) -> Result<PunctualLight, TableError> {
    let kind = raw.kind.get_ref().as_str();
    if !["sun", "point", "spot"].contains(&kind) {
        return error(
            k,
            raw.kind.span(),
            "type",
            "must be \"sun\", \"point\" or \"spot\"",
        );
    }
    check_fields(k, raw, kind)?;
    let strength = strength_of(k, raw, kind)?;
    let shape = shape_of(k, raw, kind)?;
    Ok(PunctualLight {
        shape,
        strength,
        name: raw.name.clone().unwrap_or_else(|| format!("light[{k}]")),
    })
}

/// Refuses the fields that do not belong to a light of type `kind`.
fn check_fields(k: usize, raw: &LightFile, kind: &str) -> Result<(), TableError> {
    let (sun, spot) = (kind == "sun", kind == "spot");
    let span = |s: &Option<Spanned<f32>>| s.as_ref().map(|s| s.span());
    let vspan = |s: &Option<Spanned<Vec<f32>>>| s.as_ref().map(|s| s.span());
    let fields = [
        ("intensity", span(&raw.intensity), !sun),
        ("irradiance", span(&raw.irradiance), sun),
        ("position", vspan(&raw.position), !sun),
        ("direction", vspan(&raw.direction), kind != "point"),
        ("angle", span(&raw.angle), sun),
        ("inner_angle", span(&raw.inner_angle), spot),
        ("outer_angle", span(&raw.outer_angle), spot),
    ];
    for (field, span, allowed) in fields {
        if let (Some(span), false) = (span, allowed) {
            return error(k, span, field, &format!("a {kind} light has no `{field}`"));
        }
    }
    Ok(())
}

/// Three finite numbers.
fn vec3(k: usize, s: &Spanned<Vec<f32>>, field: &str) -> Result<Vec3, TableError> {
    match s.get_ref().as_slice() {
        &[x, y, z] if [x, y, z].iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => error(k, s.span(), field, "must be an array of 3 finite numbers"),
    }
}

/// `color × irradiance` (a sun) or `color × intensity`.
fn strength_of(k: usize, raw: &LightFile, kind: &str) -> Result<Vec3, TableError> {
    let colour = match &raw.color {
        Some(c) => {
            let v = vec3(k, c, "color")?;
            if v.min_element() < 0.0 {
                return error(k, c.span(), "color", "must be non-negative");
            }
            v
        }
        None => Vec3::ONE,
    };
    let (value, field, unit) = if kind == "sun" {
        (&raw.irradiance, "irradiance", "W/m²")
    } else {
        (&raw.intensity, "intensity", "W/sr")
    };
    let Some(value) = value else {
        return error(
            k,
            raw.kind.span(),
            field,
            &format!("a {kind} light needs `{field}` ({unit})"),
        );
    };
    if !(value.get_ref().is_finite() && *value.get_ref() >= 0.0) {
        return error(
            k,
            value.span(),
            field,
            "must be a finite non-negative number",
        );
    }
    Ok(colour * *value.get_ref())
}

/// An angle in degrees from 0 to `max` (`default` where not given).
fn degrees(
    k: usize,
    s: &Option<Spanned<f32>>,
    field: &str,
    default: f32,
    max: f32,
) -> Result<f32, TableError> {
    match s {
        Some(a) if !(a.get_ref().is_finite() && (0.0..=max).contains(a.get_ref())) => error(
            k,
            a.span(),
            field,
            &format!("must be a number of degrees from 0 to {max}"),
        ),
        Some(a) => Ok(*a.get_ref()),
        None => Ok(default),
    }
}

/// The light's shape: its position, direction and angles.
fn shape_of(k: usize, raw: &LightFile, kind: &str) -> Result<LightShape, TableError> {
    let needs = |field: &str, what: &str| {
        error(
            k,
            raw.kind.span(),
            field,
            &format!("a {kind} light needs `{field}` ({what})"),
        )
    };
    let direction = match &raw.direction {
        Some(d) => {
            let v = vec3(k, d, "direction")?;
            if !(v.length_squared() > 0.0 && v.length_squared().is_finite()) {
                return error(k, d.span(), "direction", "must not be zero");
            }
            v.normalize()
        }
        None if kind != "point" => return needs("direction", "where its light goes"),
        None => Vec3::NEG_Y,
    };
    let position = match &raw.position {
        Some(p) => vec3(k, p, "position")?,
        None if kind != "sun" => return needs("position", "where it is"),
        None => Vec3::ZERO,
    };
    Ok(match kind {
        "sun" => {
            let angle = degrees(
                k,
                &raw.angle,
                "angle",
                DEFAULT_SUN_ANGLE_DEG,
                MAX_SUN_ANGLE_DEG,
            )?;
            LightShape::Sun {
                direction,
                angle: angle.to_radians(),
            }
        }
        "point" => LightShape::Point { position },
        _ => {
            let inner = degrees(k, &raw.inner_angle, "inner_angle", 0.0, 90.0)?;
            let outer = degrees(
                k,
                &raw.outer_angle,
                "outer_angle",
                DEFAULT_OUTER_ANGLE_DEG,
                90.0,
            )?;
            if inner >= outer {
                let span = raw
                    .inner_angle
                    .as_ref()
                    .map_or(raw.kind.span(), |s| s.span());
                return error(k, span, "inner_angle", "must be less than `outer_angle`");
            }
            LightShape::Spot {
                position,
                direction,
                inner: inner.to_radians(),
                outer: outer.to_radians(),
            }
        }
    })
}

/// The spot falloff of glTF's `KHR_lights_punctual` (its specification's
/// sample implementation): with `cd` the cosine of the angle between the
/// spot's axis and the direction to the lit point,
/// `clamp(cd · scale + offset, 0, 1)²`, where
/// `scale = 1 / max(0.001, cos inner − cos outer)` and
/// `offset = −cos outer · scale`. Returns `(scale, offset)`.
pub fn spot_falloff(inner: f32, outer: f32) -> (f32, f32) {
    let scale = 1.0 / (inner.cos() - outer.cos()).max(0.001);
    (scale, -outer.cos() * scale)
}
