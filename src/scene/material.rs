//! Materials: a scattering model, a reflectance and an emission.

use super::texture::TextureRef;
use glam::Vec3;

/// How a material scatters light. Each model has one scattering routine
/// (in [`crate::integrator::bsdf`]) that both engines call.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Model {
    /// Ideal diffuse (Lambertian) reflection, BRDF `ρ/π`, on both sides of
    /// the surface.
    #[default]
    Diffuse,
    /// Perfect specular reflection tinted by the reflectance (no Fresnel
    /// term), on both sides.
    Mirror,
    /// A smooth dielectric of index [`Material::ior`] (the outside is 1,
    /// on the front side of the surface): Fresnel reflection, Snell
    /// refraction tinted by [`Material::transmittance`], total internal
    /// reflection.
    Glass,
    /// A rough conductor: GGX microfacets of roughness [`Material::alpha`],
    /// with the reflectance as a constant Fresnel tint, on both sides. It
    /// supersedes the Phong lobe the report wished for: a normalised,
    /// energy-conserving glossy lobe whose α → 0 is the mirror.
    Metal,
    /// glTF 2.0's metallic-roughness material, as the specification's
    /// Appendix B defines it (a Lambertian diffuse lobe and a GGX specular
    /// lobe, Schlick Fresnel with `F0 = mix(0.04, base, metallic)`): base
    /// colour the reflectance, [`Material::metallic`],
    /// [`Material::roughness`] (α = roughness²), each possibly textured
    /// ([`Maps`]). Both sides scatter.
    MetallicRoughness,
    /// glTF 2.0's metallic-roughness material with
    /// `KHR_materials_transmission`: [`Model::MetallicRoughness`] whose
    /// diffuse base is partly ([`Material::transmission`]) replaced by a
    /// rough (or smooth) dielectric interface of index [`Material::ior`]
    /// and the same roughness, its transmission tinted by the base colour;
    /// thin-walled ([`Material::thin`]: light leaves where it enters,
    /// undeviated on average) or the boundary of a solid (refraction, as
    /// [`Model::Glass`]). Not a delta model as a whole: its smooth
    /// interface gives delta samples lane by lane.
    Transmission,
}

impl Model {
    /// The names the scene format gives the models.
    pub const NAMES: &[&str] = &[
        "diffuse",
        "mirror",
        "glass",
        "metal",
        "metallic-roughness",
        "transmission",
    ];

    /// Every model, in the order of [`Model::NAMES`].
    pub const ALL: [Model; 6] = [
        Model::Diffuse,
        Model::Mirror,
        Model::Glass,
        Model::Metal,
        Model::MetallicRoughness,
        Model::Transmission,
    ];

    /// The model named `name` in scene files.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "diffuse" => Some(Model::Diffuse),
            "mirror" => Some(Model::Mirror),
            "glass" => Some(Model::Glass),
            "metal" => Some(Model::Metal),
            "metallic-roughness" => Some(Model::MetallicRoughness),
            "transmission" => Some(Model::Transmission),
            _ => None,
        }
    }

    /// The model's name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Model::Diffuse => "diffuse",
            Model::Mirror => "mirror",
            Model::Glass => "glass",
            Model::Metal => "metal",
            Model::MetallicRoughness => "metallic-roughness",
            Model::Transmission => "transmission",
        }
    }

    /// Whether the model scatters only into isolated directions (a delta
    /// lobe): next-event estimation takes no shadow ray there, and the
    /// emission its scattered ray finds counts in full.
    pub fn is_delta(self) -> bool {
        matches!(self, Model::Mirror | Model::Glass)
    }
}

/// The index of refraction of glass when the scene gives none (crown glass).
pub const DEFAULT_IOR: f32 = 1.5;

/// The indices of refraction a scene file may give a glass material.
/// Real media lie well inside: 1.0003 (air) to about 4 (germanium in the
/// infrared); diamond is 2.42, and an index below 1 (a medium thinner than
/// the outside: an air bubble in diamond is 1/2.42 ≈ 0.41) stays above
/// 0.1. Within it `η²` and `1/η²` stay far from overflow, and the
/// refraction code from NaN (beyond it an index of `1e20` overflowed into
/// a NaN direction).
pub const IOR_RANGE: std::ops::RangeInclusive<f32> = 0.1..=10.0;

/// The GGX α below which a [`Model::Transmission`] interface is smooth
/// (delta lobes): pbrt-v4's `EffectivelySmooth` threshold (a glTF
/// roughness below about 0.032).
pub const SMOOTH_ALPHA: f32 = 1e-3;

/// The roughness of metal when the scene gives none.
pub const DEFAULT_ALPHA: f32 = 0.1;

/// The textures a material's parameters are multiplied by, looked up at
/// the hit's texture coordinates in both engines (none: the material is
/// constant, and costs what it did before textures).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Maps {
    /// Multiplies the reflectance (the base colour), RGB (sRGB-decoded).
    pub base_colour: Option<TextureRef>,
    /// [`Model::MetallicRoughness`], [`Model::Transmission`]: B multiplies
    /// [`Material::metallic`], G [`Material::roughness`] (linear).
    pub metallic_roughness: Option<TextureRef>,
    /// [`Model::Transmission`]: R multiplies [`Material::transmission`]
    /// (linear; glTF's `transmissionTexture`).
    pub transmission: Option<TextureRef>,
    /// Emitted radiance: [`emissive_factor`](Self::emissive_factor) ×
    /// this texture's RGB (sRGB-decoded) at the hit, towards the front
    /// side; [`Material::emission`] is then the factor × the texture's
    /// mean (what light sampling picks emitters by).
    pub emissive: Option<TextureRef>,
    /// The factor an [`emissive`](Self::emissive) texture multiplies
    /// (glTF's `emissiveFactor` × `KHR_materials_emissive_strength`).
    pub emissive_factor: Vec3,
    /// A tangent-space normal texture (linear; its `scale` in
    /// [`TextureRef::scale`]) that bends the shading normal, on triangles
    /// with tangents ([`Texturing::tangents`](super::Texturing::tangents)).
    pub normal: Option<TextureRef>,
}

impl Maps {
    /// Whether no scattering parameter is textured (base colour,
    /// metallic-roughness); emission is [`Maps::emissive`]'s business.
    pub fn is_empty(&self) -> bool {
        self.base_colour.is_none()
            && self.metallic_roughness.is_none()
            && self.transmission.is_none()
    }
}

/// Where a material's surface is there (glTF's `alphaMode`), by its
/// alpha: [`Material::opacity`] × the base colour texture's alpha × the
/// vertex colour's alpha, at the hit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Coverage {
    /// Everywhere (alpha is not read).
    #[default]
    Opaque,
    /// Where alpha ≥ the cutoff; rays pass through the rest.
    Mask(f32),
    /// With probability alpha: a ray passes with probability 1 − alpha,
    /// by a number that is a function of the ray's bits and the primitive
    /// (so of the path's seed, pixel, sample and vertex, like every other
    /// number).
    Blend,
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
    /// Index of refraction of [`Model::Glass`] and [`Model::Transmission`]
    /// (the medium behind the front side; the front is at index 1).
    /// Positive and finite.
    pub ior: f32,
    /// Transmittance tint of [`Model::Glass`]'s refraction, in `[0, 1]`.
    pub transmittance: Vec3,
    /// GGX roughness α of [`Model::Metal`] (the α of the distribution
    /// itself), in `[0, 1]`.
    pub alpha: f32,
    /// Metalness of [`Model::MetallicRoughness`] and
    /// [`Model::Transmission`], in `[0, 1]`.
    pub metallic: f32,
    /// Roughness of [`Model::MetallicRoughness`] and
    /// [`Model::Transmission`] (its GGX α is the square), in `[0, 1]`.
    pub roughness: f32,
    /// The transmission factor of [`Model::Transmission`], in `[0, 1]`:
    /// the share of the light that is not specularly reflected which the
    /// dielectric part transmits rather than diffusely reflects.
    pub transmission: f32,
    /// Whether a [`Model::Transmission`] surface is thin-walled (glTF
    /// without `KHR_materials_volume`, or a thickness of 0) rather than
    /// the boundary of a solid.
    pub thin: bool,
    /// Textured parameters (none by default).
    pub maps: Maps,
    /// Where the surface is there ([`Coverage::Opaque`] by default).
    pub coverage: Coverage,
    /// The alpha factor of [`Coverage`] (glTF's base colour factor's
    /// alpha; 1 by default).
    pub opacity: f32,
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
            ior: DEFAULT_IOR,
            transmittance: Vec3::ONE,
            alpha: DEFAULT_ALPHA,
            metallic: 0.0,
            roughness: 1.0,
            transmission: 0.0,
            thin: false,
            maps: Maps::default(),
            coverage: Coverage::Opaque,
            opacity: 1.0,
        }
    }

    /// What the scene's content hash takes of the model and its own
    /// parameters, as words of three floats. Diffuse, the first model,
    /// hashes as nothing: hashes of scenes from before models existed stay
    /// what they were.
    pub fn model_words(&self) -> Vec<Vec3> {
        let mut words = match self.model {
            Model::Diffuse => vec![],
            Model::Mirror => vec![Vec3::new(1.0, 0.0, 0.0)],
            Model::Glass => vec![Vec3::new(2.0, self.ior, 0.0), self.transmittance],
            Model::Metal => vec![Vec3::new(3.0, self.alpha, 0.0)],
            Model::MetallicRoughness => vec![Vec3::new(4.0, self.metallic, self.roughness)],
            Model::Transmission => vec![
                Vec3::new(8.0, self.metallic, self.roughness),
                Vec3::new(self.ior, self.transmission, f32::from(u8::from(self.thin))),
            ],
        };
        // (Opaque materials hash as before coverage existed.)
        match self.coverage {
            Coverage::Opaque => {}
            Coverage::Mask(c) => words.push(Vec3::new(5.0, c, self.opacity)),
            Coverage::Blend => words.push(Vec3::new(6.0, 0.0, self.opacity)),
        }
        // (Constant materials hash as before textures existed.)
        for (k, t) in [
            &self.maps.base_colour,
            &self.maps.metallic_roughness,
            &self.maps.emissive,
            &self.maps.normal,
            &self.maps.transmission,
        ]
        .into_iter()
        .enumerate()
        {
            if let Some(t) = t {
                words.extend(t.hash_words(k as f32));
            }
        }
        if self.maps.emissive.is_some() {
            words.push(self.maps.emissive_factor);
        }
        if let Some(n) = &self.maps.normal {
            words.push(Vec3::new(7.0, n.scale, 0.0));
        }
        words
    }

    /// Whether the material emits any light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}
