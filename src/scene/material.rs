//! Materials: a scattering model, a reflectance and an emission.

use glam::Vec3;

/// How a material scatters light. Each model has one scattering routine
/// (in [`crate::integrator::bsdf`]) that both engines call.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Model {
    /// Ideal diffuse (Lambertian) reflection, BRDF `ρ/π`, on both sides of
    /// the surface.
    #[default]
    Diffuse,
}

impl Model {
    /// The names the scene format gives the models.
    pub const NAMES: &[&str] = &["diffuse"];

    /// The model named `name` in scene files.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "diffuse" => Some(Model::Diffuse),
            _ => None,
        }
    }

    /// The model's name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Model::Diffuse => "diffuse",
        }
    }
}

/// A material: how it scatters, and what it emits.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The name the scene file gave it.
    pub name: String,
    /// The scattering model.
    pub model: Model,
    /// Reflectance ρ per RGB channel, in `[0, 1]`.
    pub reflectance: Vec3,
    /// Emitted radiance per RGB channel, towards the front side only.
    pub emission: Vec3,
}

impl Material {
    /// An ideal diffuse material of reflectance `reflectance` emitting
    /// `emission`.
    pub fn diffuse(name: &str, reflectance: Vec3, emission: Vec3) -> Self {
        Self {
            name: name.into(),
            model: Model::Diffuse,
            reflectance,
            emission,
        }
    }

    /// Whether the material emits any light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}
