//! The material seam: each scattering model is one type implementing
//! [`Bsdf`] in its own file of [`super`] (its parameters per lane, how a
//! material makes them — each a constant or looked up from a texture at
//! the hit ([`Texels`]) —, sampling with its own weight, evaluation,
//! whether it is a delta lobe), and the one list of the models, a line of
//! `bsdf/mod.rs` (`models!`), makes [`Surface`] (the scattering of a
//! surface of any model, lane by lane) and every dispatch on
//! [`Model`]: nothing else in either engine names a model.
//!
//! A new model is a variant and its row in
//! [`Model::def`](crate::scene::Model::def) (its name, the fields it
//! reads, its hash), its file here with its `impl Bsdf` and its entry in
//! the list, and its fields in the scene format if it has new ones.

#[cfg(doc)]
use super::Surface;
use super::{BsdfSample, facing, leaks};
use crate::math::{Real, V3};
use crate::scene::texture::TextureRef;
use crate::scene::{Material, Model};
use wide::f32x8;

/// What a material's textures read at a point: each textured parameter is
/// the material's factor times its texture there (glTF's rule); an
/// untextured one is the factor alone. [`Constant`] reads no texture, so
/// a model's parameters from it are its material's constants, with the
/// same bits.
pub trait Texels {
    /// What multiplies the material's colour (its reflectance, or
    /// glass's transmittance): the base colour texture times the vertex
    /// colours at the point (white without either).
    fn colour(&self) -> glam::Vec3;
    /// The texture `map` at the point (RGBA; linear, or sRGB-decoded as
    /// the map's meaning says), `None` where the material has none.
    fn read(&self, map: Option<&TextureRef>) -> Option<[f32; 4]>;
    /// Channel `c` of `map` at the point, 1 where there is no texture:
    /// what multiplies a scalar parameter.
    #[inline(always)]
    fn channel(&self, map: Option<&TextureRef>, c: usize) -> f32 {
        self.read(map).map_or(1.0, |t| t[c])
    }
    /// RGB of `map` at the point, white where there is no texture: what
    /// multiplies a colour parameter.
    #[inline(always)]
    fn rgb(&self, map: Option<&TextureRef>) -> glam::Vec3 {
        self.read(map)
            .map_or(glam::Vec3::ONE, |t| glam::Vec3::new(t[0], t[1], t[2]))
    }
}

/// No texture anywhere: every parameter is its material's constant.
#[derive(Clone, Copy, Debug)]
pub struct Constant;

impl Texels for Constant {
    #[inline(always)]
    fn colour(&self) -> glam::Vec3 {
        glam::Vec3::ONE
    }
    #[inline(always)]
    fn read(&self, _: Option<&TextureRef>) -> Option<[f32; 4]> {
        None
    }
}

/// A scattering model: its parameters and its routines, written once over
/// [`Real`] for one lane and for eight.
pub trait Bsdf {
    /// Its variant in the scene.
    const MODEL: Model;
    /// Whether it scatters only into isolated directions (a delta lobe):
    /// next-event estimation takes no shadow ray there, and the emission
    /// its scattered ray finds counts in full.
    const DELTA: bool = false;
    /// Its parameters, lane by lane.
    type Params<R: Real>: Copy;

    /// Its parameters for `material` where the material's textures read
    /// `at` ([`Constant`]: none).
    fn params(material: &Material, at: &impl Texels) -> Self::Params<f32>;

    /// Eight lanes' parameters, lane `l` being `table[rows[l]]`.
    fn gather(table: &[Self::Params<f32>], rows: &[usize; 8]) -> Self::Params<f32x8>;

    /// Where its parameters are nothing but the diffuse BRDF `ρ/π`, which
    /// the wavefront tables keep per primitive: the parameters of that
    /// BRDF (`brdf` is called only then); `None` for every other model.
    #[inline(always)]
    fn of_brdf<R: Real>(_brdf: impl FnOnce() -> V3<R>) -> Option<Self::Params<R>> {
        None
    }

    /// A scattered direction and its weight ([`BsdfSample`]) for the
    /// outgoing direction `wo`, at a surface whose ray arrived on the
    /// geometric front where `front`, of (shading) normal `n` turned
    /// towards `wo`, from the vertex's two direction numbers `u`;
    /// `uniform`: the report's estimator (uniform hemisphere directions
    /// for a diffuse lobe).
    fn sample<R: Real>(
        p: &Self::Params<R>,
        side: (R::Mask, V3<R>),
        wo: V3<R>,
        u: [R; 2],
        uniform: bool,
    ) -> BsdfSample<R>;

    /// `(f · cos θ, cos θ, pdf)` for light sampling (see
    /// [`Surface::eval`]); zero for a delta model.
    #[inline(always)]
    fn eval<R: Real>(
        _p: &Self::Params<R>,
        _n: V3<R>,
        _wo: V3<R>,
        _wi: V3<R>,
        _front: R::Mask,
    ) -> (V3<R>, R, R) {
        let zero = R::splat(0.0);
        (V3::new(zero, zero, zero), zero, zero)
    }

    /// The density to weigh the emission sample `s`'s direction finds by
    /// multiple importance sampling (see [`Surface::mis_pdf`]): 0 for a
    /// delta model, else the sample's density.
    #[inline(always)]
    fn mis_pdf<R: Real>(_p: &Self::Params<R>, s: &BsdfSample<R>, _ng: V3<R>) -> R {
        if Self::DELTA { R::splat(0.0) } else { s.pdf }
    }
}

/// Eight lanes of a scalar parameter: lane `l` is `value(rows[l])`.
/// Written out lane by lane so the lanes are built in registers: an array
/// `map` here compiled to a call that stored the eight values to memory,
/// and the vector load then waited on those stores (a sixth of the bounce
/// stage, measured).
#[inline(always)]
pub fn lanes(rows: &[usize; 8], value: impl Fn(usize) -> f32) -> f32x8 {
    f32x8::new([
        value(rows[0]),
        value(rows[1]),
        value(rows[2]),
        value(rows[3]),
        value(rows[4]),
        value(rows[5]),
        value(rows[6]),
        value(rows[7]),
    ])
}

/// Eight lanes of a colour parameter: lane `l` is `value(rows[l])`
/// ([`lanes`], per channel).
#[inline(always)]
pub fn lanes3(rows: &[usize; 8], value: impl Fn(usize) -> V3<f32>) -> V3<f32x8> {
    V3::new(
        lanes(rows, |i| value(i).x),
        lanes(rows, |i| value(i).y),
        lanes(rows, |i| value(i).z),
    )
}

/// Model `M`'s [`Surface::sample`]: the side and facing normal from the
/// geometric front normal `normal`.
#[inline(always)]
pub fn sample<M: Bsdf, R: Real>(
    p: &M::Params<R>,
    normal: V3<R>,
    d: V3<R>,
    u: [R; 2],
    uniform: bool,
) -> BsdfSample<R> {
    M::sample(p, facing(normal, d), -d, u, uniform)
}

/// Model `M`'s [`Surface::sample_shaded`]: its sample by the shading
/// normal, absorbed where it [`leaks`] through the geometric surface.
#[inline(always)]
pub fn sample_shaded<M: Bsdf, R: Real>(
    p: &M::Params<R>,
    (front, ng, ns): (R::Mask, V3<R>, V3<R>),
    d: V3<R>,
    u: [R; 2],
    uniform: bool,
) -> BsdfSample<R> {
    let s = M::sample(p, (front, ns), -d, u, uniform);
    let (zero, one) = (R::splat(0.0), R::splat(1.0));
    let leak = leaks(ns, ng, s.wi);
    BsdfSample {
        wi: s.wi,
        f: V3::select(leak, V3::new(zero, zero, zero), s.f),
        cos: R::select(leak, zero, s.cos),
        pdf: R::select(leak, one, s.pdf),
        delta: s.delta,
    }
}

/// The list of the scattering models (`Variant: type` — the variant of
/// [`Model`] and its [`Bsdf`] type), in one line of `bsdf/mod.rs`. It
/// makes [`Surface`] (one variant per model, holding its parameters),
/// its dispatching methods, [`is_delta`](super::is_delta) and the
/// per-material constant parameters ([`Constants`](super::Constants)).
macro_rules! models {
    ($($model:ident: $ty:ty),* $(,)?) => {
        /// The scattering of a surface, lane by lane: its model and that
        /// model's parameters ([`Bsdf::Params`](surface::Bsdf::Params)),
        /// the same model in every lane.
        #[derive(Clone, Copy, Debug)]
        pub enum Surface<R: $crate::math::Real> {
            $(
                #[doc = concat!("[`", stringify!($ty), "`]'s parameters.")]
                $model(<$ty as surface::Bsdf>::Params<R>),
            )*
        }

        // Each type is the model of its entry.
        $(const _: () = assert!(matches!(
            <$ty as surface::Bsdf>::MODEL,
            $crate::scene::Model::$model
        ));)*

        /// Whether `model` scatters only into isolated directions
        /// ([`Bsdf::DELTA`](surface::Bsdf::DELTA)).
        #[inline(always)]
        pub fn is_delta(model: $crate::scene::Model) -> bool {
            match model {
                $($crate::scene::Model::$model => <$ty as surface::Bsdf>::DELTA,)*
            }
        }

        impl Surface<f32> {
            /// The scattering of `material`, for one lane, where its
            /// textures read `at`.
            #[inline]
            pub fn at(material: &$crate::scene::Material, at: &impl surface::Texels) -> Self {
                match material.model {
                    $($crate::scene::Model::$model => {
                        Self::$model(<$ty as surface::Bsdf>::params(material, at))
                    })*
                }
            }

            /// The scattering of `material` with its constant parameters
            /// (no texture read), for one lane.
            #[inline]
            pub fn of(material: &$crate::scene::Material) -> Self {
                Self::at(material, &surface::Constant)
            }

            /// Eight lanes of model `model` (each lane's surface of that
            /// model): lane `l` is `lane(l)`.
            #[inline(always)]
            pub fn lanes(
                model: $crate::scene::Model,
                lane: impl Fn(usize) -> Self,
            ) -> Surface<wide::f32x8> {
                const ROWS: [usize; 8] = [0, 1, 2, 3, 4, 5, 6, 7];
                match model {
                    $($crate::scene::Model::$model => {
                        let p = ROWS.map(|l| match lane(l) {
                            Self::$model(p) => p,
                            _ => unreachable!("a lane of another model"),
                        });
                        Surface::$model(<$ty as surface::Bsdf>::gather(&p, &ROWS))
                    })*
                }
            }
        }

        impl<R: $crate::math::Real> Surface<R> {
            /// The model.
            #[inline(always)]
            pub fn model(&self) -> $crate::scene::Model {
                match self {
                    $(Self::$model(_) => $crate::scene::Model::$model,)*
                }
            }

            /// The density to weigh, by multiple importance sampling, the
            /// emission that the direction of sample `s` finds, at a
            /// surface of geometric facing normal `ng` ([`facing`]): 0
            /// where light sampling could not have found it — after a
            /// delta sample (of a delta model, or a smooth transmission
            /// lane), and after a transmission (light sampling connects
            /// only on the side of `ng`) — else the sample's density.
            #[inline(always)]
            pub fn mis_pdf(&self, s: &BsdfSample<R>, ng: $crate::math::V3<R>) -> R {
                match self {
                    $(Self::$model(p) => <$ty as surface::Bsdf>::mis_pdf(p, s, ng),)*
                }
            }

            /// The scattered direction of a ray of direction `d` that hit
            /// the surface of geometric (front) unit normal `normal`, from
            /// the vertex's two direction numbers `u`. Diffuse surfaces
            /// draw uniform hemisphere directions when `uniform` (the
            /// report's estimator), cosine-weighted ones otherwise; glass
            /// chooses reflection or refraction with `u[0]`.
            #[inline(always)]
            pub fn sample(
                &self,
                normal: $crate::math::V3<R>,
                d: $crate::math::V3<R>,
                u: [R; 2],
                uniform: bool,
            ) -> BsdfSample<R> {
                match self {
                    $(Self::$model(p) => surface::sample::<$ty, R>(p, normal, d, u, uniform),)*
                }
            }

            /// [`sample`](Self::sample) at a smooth surface: `front` and
            /// `ng`, the geometric side and facing normal ([`facing`]),
            /// decide the side; the shading facing normal `ns`
            /// ([`shading_facing`]) orients the lobe (glass takes it
            /// turned outward, to the geometric front). A direction that
            /// [`leaks`] through the geometric surface is absorbed:
            /// `f = 0`, `cos = 0`, `pdf = 1` (weight exactly zero), as the
            /// [`BsdfSample`] contract has absorbed samples. With
            /// `ns == ng` (flat) it is [`sample`](Self::sample), bit for
            /// bit.
            #[inline(always)]
            pub fn sample_shaded(
                &self,
                hit: (R::Mask, $crate::math::V3<R>, $crate::math::V3<R>),
                d: $crate::math::V3<R>,
                u: [R; 2],
                uniform: bool,
            ) -> BsdfSample<R> {
                match self {
                    $(Self::$model(p) => surface::sample_shaded::<$ty, R>(p, hit, d, u, uniform),)*
                }
            }

            /// For light sampling at a non-delta surface of facing unit
            /// normal `n` (turned towards `wo`; `front`: `wo` is on the
            /// geometric front): `(f · cos θ, cos θ, pdf)` for the
            /// direction `wi` on the side of `wo`, with `pdf` the density
            /// [`sample`](Self::sample) draws `wi` with (cosine-weighted
            /// for diffuse). Zero where the surface does not scatter `wo`
            /// into `wi`, and for `wi` on the other side; delta models
            /// give zero everywhere.
            #[inline(always)]
            pub fn eval(
                &self,
                n: $crate::math::V3<R>,
                wo: $crate::math::V3<R>,
                wi: $crate::math::V3<R>,
                front: R::Mask,
            ) -> ($crate::math::V3<R>, R, R) {
                match self {
                    $(Self::$model(p) => <$ty as surface::Bsdf>::eval(p, n, wo, wi, front),)*
                }
            }
        }

        /// Every material's constant parameters, per model (a column per
        /// model, indexed by material: a material of another model has
        /// that model's reading of its fields, never used), for the
        /// wavefront engine's eight lanes at a time.
        #[allow(non_snake_case, reason = "one column per model, named as its variant")]
        #[derive(Clone)]
        pub struct Constants {
            $($model: Vec<<$ty as surface::Bsdf>::Params<f32>>,)*
        }

        impl Constants {
            /// The constant parameters of `materials`.
            pub fn new(materials: &[$crate::scene::Material]) -> Self {
                Self {
                    $($model: (materials.iter())
                        .map(|m| <$ty as surface::Bsdf>::params(m, &surface::Constant))
                        .collect(),)*
                }
            }

            /// The surfaces of eight lanes of materials `materials()`, all
            /// of model `model`: from `brdf()` (the lanes' diffuse BRDF,
            /// where the model's parameters are that:
            /// [`Bsdf::of_brdf`](surface::Bsdf::of_brdf)), else gathered
            /// from the materials' columns. (Each is called only where it
            /// is read.)
            #[inline(always)]
            pub fn gather(
                &self,
                model: $crate::scene::Model,
                materials: impl FnOnce() -> [usize; 8],
                brdf: impl FnOnce() -> $crate::math::V3<wide::f32x8>,
            ) -> Surface<wide::f32x8> {
                match model {
                    $($crate::scene::Model::$model => Surface::$model(
                        match <$ty as surface::Bsdf>::of_brdf(brdf) {
                            Some(p) => p,
                            None => <$ty as surface::Bsdf>::gather(&self.$model, &materials()),
                        },
                    ),)*
                }
            }
        }
    };
}
pub(crate) use models;
