//! Materials: a scattering model, a reflectance and an emission.

use super::texture::TextureRef;
use glam::Vec3;

/// How a material scatters light. Each model has one scattering type (in
/// [`crate::integrator::bsdf`], listed there once) that both engines
/// call; what the scene knows of it — its name, the material fields it
/// reads, its content hash — is its row of [`Model::def`]. A new model is
/// its variant, its entry in [`Model::ALL`] and its row here, its file in
/// the `bsdf` module with its entry in that module's list, and its new
/// fields (if any) in the scene format.
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
    /// Every model, in the order of their variants (the order the
    /// wavefront engine groups paths in).
    pub const ALL: [Model; 6] = [
        Model::Diffuse,
        Model::Mirror,
        Model::Glass,
        Model::Metal,
        Model::MetallicRoughness,
        Model::Transmission,
    ];

    /// The names the scene format gives the models, in the order of
    /// [`Model::ALL`].
    pub const NAMES: [&str; Self::ALL.len()] = {
        let mut names = [""; Self::ALL.len()];
        let mut i = 0;
        while i < names.len() {
            names[i] = Self::ALL[i].def().name;
            i += 1;
        }
        names
    };

    /// The model named `name` in scene files.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The model's name in scene files.
    pub fn name(self) -> &'static str {
        self.def().name
    }

    /// Whether the model reads the material field `field` (a key of the
    /// scene format's material table, as [`ModelDef::fields`] lists them).
    pub fn reads(self, field: &str) -> bool {
        self.def().fields.contains(&field)
    }

    /// The names of the models that read `field`, for messages: "a, b
    /// and c".
    pub fn readers(field: &str) -> String {
        let names: Vec<&str> = (Self::ALL.into_iter())
            .filter(|m| m.reads(field))
            .map(Model::name)
            .collect();
        match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => names.join(""),
        }
    }

    /// What the scene knows of the model: one row per model. (How it
    /// scatters is its [`Bsdf`](crate::integrator::bsdf::surface::Bsdf)
    /// implementation's business.)
    pub const fn def(self) -> ModelDef {
        match self {
            Model::Diffuse => ModelDef {
                name: "diffuse",
                fields: &["reflectance"],
                // The first model hashes as nothing: hashes of scenes
                // from before models existed stay what they were.
                words: |_| vec![],
                solid: |_| false,
            },
            Model::Mirror => ModelDef {
                name: "mirror",
                fields: &["reflectance"],
                words: |_| vec![Vec3::new(1.0, 0.0, 0.0)],
                solid: |_| false,
            },
            Model::Glass => ModelDef {
                name: "glass",
                fields: &["ior", "transmittance"],
                words: |m| vec![Vec3::new(2.0, m.ior, 0.0), m.transmittance],
                solid: |_| true,
            },
            Model::Metal => ModelDef {
                name: "metal",
                fields: &["reflectance", "alpha"],
                words: |m| vec![Vec3::new(3.0, m.alpha, 0.0)],
                solid: |_| false,
            },
            Model::MetallicRoughness => ModelDef {
                name: "metallic-roughness",
                fields: &["reflectance", "metallic", "roughness"],
                words: |m| {
                    let mut words = vec![Vec3::new(4.0, m.metallic, m.roughness)];
                    words.extend(m.specular_words());
                    // (Materials of the default index hash as before
                    // indices reached this model.)
                    if m.ior != DEFAULT_IOR {
                        words.push(Vec3::new(10.0, m.ior, 0.0));
                    }
                    words
                },
                solid: |_| false,
            },
            Model::Transmission => ModelDef {
                name: "transmission",
                fields: &[
                    "reflectance",
                    "metallic",
                    "roughness",
                    "ior",
                    "transmission",
                    "thin",
                ],
                words: |m| {
                    let mut words = vec![
                        Vec3::new(8.0, m.metallic, m.roughness),
                        Vec3::new(m.ior, m.transmission, f32::from(u8::from(m.thin))),
                    ];
                    words.extend(m.specular_words());
                    words
                },
                solid: |m| !m.thin,
            },
        }
    }
}

/// What the scene knows of a scattering model ([`Model::def`]).
#[derive(Clone, Copy, Debug)]
pub struct ModelDef {
    /// Its name in scene files.
    pub name: &'static str,
    /// The fields of the scene format's material table it reads besides
    /// `model` and `emission` (a material of a model without
    /// `reflectance` is white).
    pub fields: &'static [&'static str],
    /// What the scene's content hash takes of a material of the model:
    /// the model and its own parameters, as words of three floats.
    pub words: fn(&Material) -> Vec<Vec3>,
    /// Whether a material of the model is the boundary of a solid (light
    /// inside it may be absorbed: [`Material::absorbs`]).
    pub solid: fn(&Material) -> bool,
}

/// The index of refraction of glass when the scene gives none (crown glass).
pub const DEFAULT_IOR: f32 = 1.5;

/// The `F0` of a dielectric of index `ior` against the outside (index
/// 1): `((ior − 1) / (ior + 1))²`, exactly [`DIELECTRIC_F0`] (glTF's
/// 0.04) for the default index [`DEFAULT_IOR`] (so materials of the
/// default index compute what they did before indices reached the
/// metallic-roughness model); 1 for an index of 0 (the specification's
/// specular-glossiness conversion).
#[inline]
pub fn f0_of_ior(ior: f32) -> f32 {
    if ior == DEFAULT_IOR {
        return DIELECTRIC_F0;
    }
    let r = (ior - 1.0) / (ior + 1.0);
    r * r
}

/// glTF's `F0` of a dielectric of the default index (1.5).
pub const DIELECTRIC_F0: f32 = 0.04;

/// The dielectric `F0` colour of `KHR_materials_specular` before its
/// strength: `min(F0(ior) × colour, 1)` per channel ([`f0_of_ior`]).
/// Times the strength it is the specification's `dielectric_f0`.
#[inline]
pub fn dielectric_f0(ior: f32, colour: Vec3) -> Vec3 {
    (colour * f0_of_ior(ior)).min(Vec3::ONE)
}

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
    /// [`Model::MetallicRoughness`], [`Model::Transmission`]: A multiplies
    /// [`Material::specular`] (glTF's `KHR_materials_specular`
    /// `specularTexture`, linear).
    pub specular: Option<TextureRef>,
    /// [`Model::MetallicRoughness`], [`Model::Transmission`]: RGB
    /// multiplies [`Material::specular_colour`] (`specularColorTexture`,
    /// sRGB-decoded).
    pub specular_colour: Option<TextureRef>,
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
            && self.specular.is_none()
            && self.specular_colour.is_none()
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
    /// `KHR_materials_specular`'s strength of the dielectric specular
    /// reflection of [`Model::MetallicRoughness`] and
    /// [`Model::Transmission`], in `[0, 1]` (1 by default): the dielectric
    /// `F90`, and a factor of its `F0`.
    pub specular: f32,
    /// `KHR_materials_specular`'s colour of the dielectric `F0`
    /// (linear RGB, non-negative; white by default): `F0 = min(F0(ior) ×
    /// colour, 1) × specular` ([`dielectric_f0`]).
    pub specular_colour: Vec3,
    /// `KHR_materials_volume`'s attenuation colour of a solid
    /// [`Model::Transmission`] or [`Model::Glass`] medium (linear RGB in
    /// `[0, 1]`): what white light becomes after
    /// [`attenuation_distance`](Self::attenuation_distance) inside it
    /// (white by default: no absorption).
    pub attenuation_colour: Vec3,
    /// The distance (scene units) over which light inside the medium
    /// turns [`attenuation_colour`](Self::attenuation_colour); positive,
    /// infinite by default (no absorption).
    pub attenuation_distance: f32,
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
            specular: 1.0,
            specular_colour: Vec3::ONE,
            attenuation_colour: Vec3::ONE,
            attenuation_distance: f32::INFINITY,
            maps: Maps::default(),
            coverage: Coverage::Opaque,
            opacity: 1.0,
        }
    }

    /// What the scene's content hash takes of the model and its own
    /// parameters ([`ModelDef::words`]), then of absorption, coverage and
    /// textures, as words of three floats.
    pub fn model_words(&self) -> Vec<Vec3> {
        let mut words = (self.model.def().words)(self);
        if self.absorbs() {
            words.push(Vec3::new(11.0, self.attenuation_distance, 0.0));
            words.push(self.attenuation_colour);
        }
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
            &self.maps.specular,
            &self.maps.specular_colour,
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

    /// Whether light travelling inside the material is absorbed: a solid
    /// ([`Model::Glass`], or [`Model::Transmission`] not thin-walled) with
    /// a finite [`attenuation_distance`](Self::attenuation_distance) and
    /// an [`attenuation_colour`](Self::attenuation_colour) other than
    /// white.
    pub fn absorbs(&self) -> bool {
        (self.model.def().solid)(self)
            && self.attenuation_distance.is_finite()
            && self.attenuation_colour != Vec3::ONE
    }

    /// The transmittance of a straight path of length `t` inside the
    /// material, per RGB channel (Beer–Lambert, as `KHR_materials_volume`
    /// defines it): `attenuation_colour^(t / attenuation_distance)`, i.e.
    /// `exp(−σ t)` with `σ = −ln(colour) / distance`; `None` where the
    /// material does not absorb ([`absorbs`](Self::absorbs)). A channel
    /// of colour 0 is black for any `t > 0`.
    #[inline]
    pub fn transmittance(&self, t: f32) -> Option<[f32; 3]> {
        if !self.absorbs() {
            return None;
        }
        let x = t / self.attenuation_distance;
        let c = self.attenuation_colour;
        Some([c.x.powf(x), c.y.powf(x), c.z.powf(x)])
    }

    /// `KHR_materials_specular`'s words for the content hash, none for
    /// the defaults (materials of the default specular hash as before it
    /// existed).
    pub fn specular_words(&self) -> Vec<Vec3> {
        if self.specular != 1.0 || self.specular_colour != Vec3::ONE {
            vec![Vec3::new(9.0, self.specular, 0.0), self.specular_colour]
        } else {
            vec![]
        }
    }

    /// Whether the material emits any light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}
