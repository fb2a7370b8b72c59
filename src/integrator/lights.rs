//! The emitters of a scene, for next-event estimation: an emitter is
//! chosen in proportion to its power, then a point on it — on a rectangle
//! uniformly by the solid angle it subtends at the shading point
//! ([`SphericalRectangle`]), elsewhere uniformly by area.
//!
//! Each shape kind lists its emitters and samples points on them by area
//! ([`Shape::emitters`], [`Shape::sample_area`]); the lights go through
//! the kinds' list ([`Kinds`]) and name no kind but the first, triangles,
//! whose pairs may be rectangles sampled by solid angle. Every emissive
//! triangle is an emitter, except that two emissive
//! triangles of one material that share an edge and together form a
//! parallelogram (a quad light made of two triangles, as the Cornell box's)
//! are one emitter: a point on it is the unit square's point mapped
//! linearly, one emitter to pick instead of two and no warp to a triangle;
//! a parallelogram with square corners is a rectangle. Each emissive
//! sphere is an emitter. Its power is proportional to
//! `area × mean(emitted radiance)` (a one-sided Lambertian emitter sends
//! `π · area · L` into its hemisphere). The density of a point sampled by
//! area, per unit area, is `P(emitter) / area`; seen from a point `x` at
//! distance `r`, with the emitter's normal at angle `θ_l` to the direction
//! back to `x`, it is `P(emitter) / area · r² / cos θ_l` per unit solid
//! angle. A point sampled by solid angle has density `P(emitter) / Ω`,
//! `Ω` the rectangle's solid angle at `x`.
//!
//! A scene's environment ([`EnvLight`]) is one more emitter, last in the
//! running sums, of power `4π r² × mean radiance` (`r` the radius of the
//! scene's bounding sphere: the power it sends through that sphere, over
//! `π` as for the other emitters); a direction drawn from it has density
//! `P(environment) × p(direction)` per unit solid angle. Scenes without
//! one sample exactly as before.

use super::environment::{EnvLight, pick_lanes, sorted};
use super::light_tree::{LightBounds, LightTree, TREE_MIN_EMITTERS};
use super::punctual::Punctual;
use crate::accel::shape::{AreaShape, Family, Kinds, Make, Shape, Shapes, Visit};
use crate::accel::triangle::TriangleEdges;
pub use crate::accel::triangle::square_to_triangle;
use crate::math::{Real, V3, acos, sin_cos_2pi};
use crate::scene::Scene;
use glam::Vec3;
use wide::{f32x8, i32x8};

/// The scene's emitters, with what sampling them needs.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Primitive index of each emitter (the kinds in order; a
    /// parallelogram: its first triangle).
    triangle: Vec<u32>,
    /// Running sums of the emitters' powers, normalised to end at 1.
    cdf: Vec<f32>,
    /// Each emitter's geometry and radiance.
    emitters: Vec<Emitter>,
    /// The emitter of each primitive ([`NOT_EMITTER`] for primitives that
    /// do not emit), so a hit can look its density up.
    emitter_of: Vec<u32>,
    /// Which kinds have emitters.
    kinds: Kinds<Flag>,
    /// Whether some emitters are of another kind than the first
    /// (triangles): their points are then chosen lane by lane by kind.
    mixed: bool,
    /// Whether some emitters are rectangles (sampled by solid angle).
    has_rectangles: bool,
    /// The scene's environment, if it has one.
    environment: Option<EnvLight>,
    /// The probability that the environment is picked (0: it is black,
    /// or there is none; then `cdf` has no entry for it).
    environment_probability: f32,
    /// A distance from any point of the scene to beyond its bounds: a
    /// direction drawn from the environment is a point this far away.
    far: f32,
    /// The scene's sun, point and spot lights that send light, after the
    /// emitters in the running sums (before the environment).
    punctual: Vec<Punctual>,
    /// Whether some of them are suns that rays leaving the scene see.
    suns: bool,
    /// Where the scene has more than [`TREE_MIN_EMITTERS`] emitters: the
    /// tree that picks one of them by its importance at the shading point
    /// (then `cdf` has one entry for all the emitters, the tree's).
    tree: Option<LightTree>,
    /// With a tree: the probability that it is picked (the emitters'
    /// share of the power), and each emitter's area.
    tree_probability: f32,
    areas: Vec<f32>,
    /// Where [`sample_8`](Self::sample_8) needs no pick (one emitter, no
    /// tree, nothing else to sample): that emitter in all eight lanes,
    /// splatted once here rather than at every call.
    single_8: Option<Box<Emitter<f32x8>>>,
    /// Where moreover that emitter is a rectangle of the first kind: it in
    /// all sixteen lanes of [`Pair`], for [`sample_16`](Self::sample_16).
    single_16: Option<Box<Emitter<Pair>>>,
    /// Whether [`sample_8`](Self::sample_8) picks among the emitters,
    /// punctual lights and environment in lanes ([`pick_lanes`]): the
    /// scene has some of the latter two, and its running sums never
    /// decrease and hold no NaN (a scene of overflowing size may make
    /// them NaN; then lane by lane).
    pick_in_lanes: bool,
    /// Where the scene has exactly one emitter besides punctual lights or
    /// an environment, and no tree: it in all eight lanes.
    only_8: Option<Box<Emitter<f32x8>>>,
}

/// One emitter (`R = f32`) or eight (`R = f32x8`) of any kind (a
/// triangle, a parallelogram, a sphere), its radiance and its sampling
/// density.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Emitter<R = f32> {
    /// Vertex 0 (a parallelogram: the corner its edges start from; a
    /// sphere: its center).
    pub v0: V3<R>,
    /// `v1 - v0` (a parallelogram: one edge from `v0`).
    pub e1: V3<R>,
    /// `v2 - v0` (a parallelogram: the other edge from `v0`).
    pub e2: V3<R>,
    /// Front-side unit normal (a sphere: unused).
    pub normal: V3<R>,
    /// The radiance it emits towards its front.
    pub emission: V3<R>,
    /// The density of its points per unit area: `P(emitter) / area`.
    pub pdf_area: R,
    /// The probability `P(emitter)` that it is picked.
    pub probability: R,
    /// 0 for a triangle or a parallelogram; a sphere's radius.
    pub radius: R,
    /// 1 for a parallelogram (the points `v0 + a e1 + b e2`, `a` and `b`
    /// in `[0, 1]`), 0 for a triangle or a sphere.
    pub parallelogram: R,
    /// 1 for a rectangle (a parallelogram with square corners): its points
    /// are sampled by solid angle where it looks large enough
    /// ([`SphericalRectangle`]); 0 otherwise.
    pub rectangle: R,
    /// A rectangle's edges as unit vectors (`e1`, `e2` normalised).
    pub axes: [V3<R>; 2],
    /// A rectangle's edge lengths (`|e1|`, `|e2|`).
    pub lengths: [R; 2],
    /// The largest [`Scene::primitive_scale`] of its primitives: what the
    /// rounding of a shadow ray's end on it is proportional to
    /// ([`crate::integrator::offset`]).
    pub scale: R,
    /// The bits of its primitive's index (a parallelogram: its first
    /// triangle's; [`NO_PRIM_BITS`] for none): where a point on it reads
    /// a textured emission ([`Tables::light_emission`](super::tables::Tables::light_emission)).
    pub prim: R,
    /// Its kind's number ([`Kind::KIND`](crate::accel::shape::Kind::KIND)).
    pub kind: R,
}

/// Whether each kind has emitters.
#[derive(Clone, Copy, Debug, Default)]
struct Flag;

impl Family for Flag {
    type Of<S: Shape> = bool;
}

/// [`Emitter::prim`] of no primitive (the environment, [`Emitter::NONE`]):
/// `f32::MAX`, whose bits index past any scene's primitives (and, unlike a
/// NaN, equal themselves).
pub const NO_PRIM_BITS: f32 = f32::MAX;

/// In [`Lights::emitter_of`]: the primitive does not emit.
const NOT_EMITTER: u32 = u32::MAX;

/// The largest `f32` below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

const ZERO: V3<f32> = V3 {
    x: 0.0,
    y: 0.0,
    z: 0.0,
};

/// Number of floats in an [`Emitter`].
const EMITTER_FLOATS: usize = 31;

impl Emitter {
    /// The emitter's floats, in field order.
    #[inline(always)]
    fn floats(&self) -> [f32; EMITTER_FLOATS] {
        let mut f = [0.0; EMITTER_FLOATS];
        let v3s = [
            self.v0,
            self.e1,
            self.e2,
            self.normal,
            self.emission,
            self.axes[0],
            self.axes[1],
        ];
        for (k, v) in v3s.iter().enumerate() {
            f[3 * k..3 * k + 3].copy_from_slice(&[v.x, v.y, v.z]);
        }
        f[21..].copy_from_slice(&[
            self.pdf_area,
            self.probability,
            self.radius,
            self.parallelogram,
            self.rectangle,
            self.lengths[0],
            self.lengths[1],
            self.scale,
            self.prim,
            self.kind,
        ]);
        f
    }

    /// No emitter: a point sampled on it never carries light (its normal
    /// is zero, so it faces nothing).
    pub const NONE: Emitter = Emitter {
        v0: ZERO,
        e1: ZERO,
        e2: ZERO,
        normal: ZERO,
        emission: ZERO,
        pdf_area: 0.0,
        probability: 0.0,
        radius: 0.0,
        parallelogram: 0.0,
        rectangle: 0.0,
        axes: [ZERO; 2],
        lengths: [0.0; 2],
        scale: 0.0,
        prim: NO_PRIM_BITS,
        kind: 0.0,
    };
}

impl Emitter {
    /// Its bounds for the light tree, with power `power`: its box (a
    /// sphere's: its centre ± its radius) and normal (a sphere: normals
    /// every way).
    fn bounds(&self, power: f64) -> LightBounds {
        let (v0, e1, e2) = (
            Vec3::from(self.v0),
            Vec3::from(self.e1),
            Vec3::from(self.e2),
        );
        if self.radius > 0.0 {
            let r = Vec3::splat(self.radius);
            return LightBounds::emitter(v0 - r, v0 + r, power as f32, Vec3::Z, false);
        }
        let mut corners = vec![v0, v0 + e1, v0 + e2];
        if self.parallelogram > 0.0 {
            corners.push(v0 + e1 + e2);
        }
        let lo = corners.iter().fold(Vec3::INFINITY, |a, &c| a.min(c));
        let hi = corners.iter().fold(Vec3::NEG_INFINITY, |a, &c| a.max(c));
        LightBounds::emitter(lo, hi, power as f32, self.normal.into(), true)
    }
}

impl<R: Real> Emitter<R> {
    /// The emitter whose fields are `f` (in [`Emitter::floats`] order).
    #[inline(always)]
    fn from_floats(f: [R; EMITTER_FLOATS]) -> Self {
        let v3 = |k: usize| V3::new(f[k], f[k + 1], f[k + 2]);
        Self {
            v0: v3(0),
            e1: v3(3),
            e2: v3(6),
            normal: v3(9),
            emission: v3(12),
            axes: [v3(15), v3(18)],
            pdf_area: f[21],
            probability: f[22],
            radius: f[23],
            parallelogram: f[24],
            rectangle: f[25],
            lengths: [f[26], f[27]],
            scale: f[28],
            prim: f[29],
            kind: f[30],
        }
    }

    /// Its geometry, as its kind's [`Shape::sample_area`] reads it.
    #[inline(always)]
    pub fn area_shape(&self) -> AreaShape<R> {
        AreaShape {
            v0: self.v0,
            e1: self.e1,
            e2: self.e2,
            normal: self.normal,
            radius: self.radius,
            parallelogram: self.parallelogram,
        }
    }
}

impl Emitter<f32x8> {
    /// Eight emitters, one per lane.
    #[inline(always)]
    pub fn lanes(e: [&Emitter; 8]) -> Self {
        // Transposed field by field: an emitter is plain floats.
        let mut cols = [[0.0f32; 8]; EMITTER_FLOATS];
        for (l, e) in e.iter().enumerate() {
            for (col, x) in cols.iter_mut().zip(e.floats()) {
                col[l] = x;
            }
        }
        Self::from_floats(cols.map(f32x8::from))
    }

    /// One emitter in all eight lanes.
    #[inline(always)]
    pub fn splat(e: &Emitter) -> Self {
        Self::from_floats(e.floats().map(f32x8::splat))
    }
}

/// Whether some kind but the first has emitters.
struct OtherKinds;

impl Visit<Flag> for OtherKinds {
    fn visit<S: Shape>(&mut self, has: &bool) -> bool {
        S::KIND != 0 && *has
    }
}

/// [`Lights::point_on`]'s points of the kinds after the first: each
/// kind's, where it has emitters, in the lanes of its emitters.
struct ByKind<'a, R> {
    emitter: &'a Emitter<R>,
    u: [R; 2],
    p: LightPoint<R>,
}

impl<R: Real> Visit<Flag> for ByKind<'_, R> {
    #[inline(always)]
    fn visit<S: Shape>(&mut self, has: &bool) -> bool {
        if S::KIND != 0 && *has {
            let (point, normal) = S::sample_area(&self.emitter.area_shape(), self.u);
            let mine = self.emitter.kind.eq(R::splat(S::KIND as f32));
            self.p.point = V3::select(mine, point, self.p.point);
            self.p.normal = V3::select(mine, normal, self.p.normal);
        }
        false
    }
}

/// Rectangles that look smaller than this (in steradians) from a point
/// are sampled there by area, not by solid angle: a small solid angle is
/// the difference of nearly equal angles, too inexact to sample by, and
/// area sampling is then nearly as good.
pub const MIN_SOLID_ANGLE: f32 = 0.02;

/// A rectangle emitter as seen from a point `o`: the spherical rectangle
/// of Ureña, Fajardo and King ("An Area-Preserving Parametrization for
/// Spherical Rectangles", EGSR 2013), which maps the unit square onto the
/// rectangle's points uniformly by the solid angle they subtend at `o`.
///
/// In the rectangle's frame (`x`, `y` its edges from corner `v0`, `z`
/// their cross product turned away from `o`), `o` sees the corner at
/// `(x0, y0, z0)`, `z0 ≤ 0`, and the rectangle spans `[x0, x1] × [y0, y1]`
/// at height `z0`. Written once over [`Real`], so one lane and eight
/// compute the same bits.
#[derive(Clone, Copy, Debug)]
pub struct SphericalRectangle<R> {
    x0: R,
    x1: R,
    y0: R,
    y1: R,
    z0: R,
    b0: R,
    b1: R,
    k: R,
    /// The solid angle the rectangle subtends at `o`.
    pub solid_angle: R,
}

impl<R: Real> SphericalRectangle<R> {
    /// The rectangle `e` (its `axes` and `lengths`) seen from `o`.
    #[inline(always)]
    pub fn new(e: &Emitter<R>, o: V3<R>) -> Self {
        let [ax, ay] = e.axes;
        let d = e.v0 - o;
        let z0 = -d.dot(ax.cross(ay)).abs();
        let (x0, y0) = (d.dot(ax), d.dot(ay));
        let (x1, y1) = (x0 + e.lengths[0], y0 + e.lengths[1]);
        // The unit normals of the four planes through `o` and an edge:
        // n0 = (0, z0, -y0)/l0, n1 = (-z0, 0, x1)/l1, n2 = (0, -z0, y1)/l2,
        // n3 = (z0, 0, -x0)/l3; the spherical rectangle's inner angles are
        // acos(-ni · ni+1).
        let z2 = z0 * z0;
        let (l0, l1) = (y0.mul_add(y0, z2).sqrt(), x1.mul_add(x1, z2).sqrt());
        let (l2, l3) = (y1.mul_add(y1, z2).sqrt(), x0.mul_add(x0, z2).sqrt());
        let g0 = acos((y0 * x1) / (l0 * l1));
        let g1 = acos(-(x1 * y1) / (l1 * l2));
        let g2 = acos((x0 * y1) / (l2 * l3));
        let g3 = acos(-(x0 * y0) / (l3 * l0));
        let k = R::splat(std::f32::consts::TAU) - g2 - g3;
        Self {
            x0,
            x1,
            y0,
            y1,
            z0,
            b0: -y0 / l0,
            b1: y1 / l2,
            k,
            solid_angle: g0 + g1 - k,
        }
    }

    /// The point of the rectangle `e` (seen from `o`, as in [`new`]) for
    /// the numbers `u`, uniform by solid angle.
    ///
    /// [`new`]: SphericalRectangle::new
    #[inline(always)]
    pub fn sample(&self, e: &Emitter<R>, [u, v]: [R; 2]) -> V3<R> {
        let (zero, one) = (R::splat(0.0), R::splat(1.0));
        // The azimuth: a cut through `o` at angle `au` holds the fraction
        // `u` of the solid angle; it crosses the rectangle at `x = xu`.
        let au = u.mul_add(self.solid_angle, self.k);
        let (sin, cos) = sin_cos_2pi(au * R::splat(1.0 / std::f32::consts::TAU));
        let fu = cos.mul_add(self.b0, -self.b1) / sin;
        let cu = one / fu.mul_add(fu, self.b0 * self.b0).sqrt();
        let cu = R::select(fu.lt(zero), -cu, cu).min(one).max(-one);
        let xu = -(cu * self.z0) / (-cu).mul_add(cu, one).max(zero).sqrt();
        let xu = xu.max(self.x0).min(self.x1);
        // The elevation, linear in `v` along the cut.
        let dd = xu.mul_add(xu, self.z0 * self.z0).sqrt();
        let d2 = dd * dd;
        let h0 = self.y0 / self.y0.mul_add(self.y0, d2).sqrt();
        let h1 = self.y1 / self.y1.mul_add(self.y1, d2).sqrt();
        let hv = v.mul_add(h1 - h0, h0);
        let hv2 = hv * hv;
        let yv = R::select(
            hv2.lt(R::splat(1.0 - 1e-6)),
            (hv * dd) / (one - hv2).sqrt(),
            self.y1,
        );
        let yv = yv.max(self.y0).min(self.y1);
        let [ax, ay] = e.axes;
        ay.mul_add(yv - self.y0, ax.mul_add(xu - self.x0, e.v0))
    }

    /// Whether `e` is a rectangle sampled by solid angle from this point.
    #[inline(always)]
    pub fn used(&self, e: &Emitter<R>) -> R::Mask {
        R::splat(0.0).lt(e.rectangle) & R::splat(MIN_SOLID_ANGLE).lt(self.solid_angle)
    }
}

/// A point on an emitter, as next-event estimation uses it: one
/// (`R = f32`) or eight (`R = f32x8`).
#[derive(Clone, Copy, Debug)]
pub struct LightPoint<R> {
    /// The point.
    pub point: V3<R>,
    /// The emitter's front-side unit normal.
    pub normal: V3<R>,
    /// The radiance it emits towards its front.
    pub emission: V3<R>,
    /// The point's density per unit area, when it was sampled by area.
    pub pdf_area: R,
    /// The point's density per unit solid angle at the shading point, when
    /// it was sampled by solid angle; 0 when it was sampled by area.
    pub pdf_solid_angle: R,
    /// The emitter's [`Emitter::scale`].
    pub scale: R,
    /// The emitter's [`Emitter::prim`] (bits).
    pub prim: R,
    /// 1 for a delta light (a point or spot light, a sun of diameter 0:
    /// `pdf_solid_angle` is then the probability it was picked, and no
    /// other strategy can find it, so its MIS weight is 1); 0 otherwise.
    pub delta: R,
}

impl<R: Real> LightPoint<R> {
    /// The point `u` (two numbers) of the emitter `e`, for a shading point
    /// `o`: on a rectangle that looks large enough from `o`, uniform by
    /// the solid angle it subtends at `o` ([`SphericalRectangle`]); else
    /// uniform by area, on a triangle through [`square_to_triangle`], on a
    /// parallelogram the square mapped linearly.
    #[inline(always)]
    pub fn on(e: &Emitter<R>, o: V3<R>, u: [R; 2]) -> Self {
        let by_area = Self::on_by_area(e, u);
        let rect = SphericalRectangle::new(e, o);
        let solid = rect.used(e);
        Self {
            point: V3::select(solid, rect.sample(e, u), by_area.point),
            pdf_solid_angle: R::select(solid, e.probability / rect.solid_angle, R::splat(0.0)),
            ..by_area
        }
    }

    /// [`LightPoint::on`] where `e` is no rectangle (the same bits, without
    /// setting up a spherical rectangle): uniform by area, as the first
    /// kind, triangles, sample it ([`Shape::sample_area`]).
    #[inline(always)]
    pub fn on_by_area(e: &Emitter<R>, u: [R; 2]) -> Self {
        let (point, normal) = TriangleEdges::sample_area(&e.area_shape(), u);
        Self {
            point,
            normal,
            emission: e.emission,
            pdf_area: e.pdf_area,
            pdf_solid_angle: R::splat(0.0),
            scale: e.scale,
            prim: e.prim,
            delta: R::splat(0.0),
        }
    }
}

impl Lights {
    /// The emitters of `scene`: its triangles whose material emits and
    /// whose area is not zero (pairs that form a parallelogram as one,
    /// see the module documentation), then its emissive spheres.
    pub fn new(scene: &Scene) -> Self {
        /// Each kind's emitters into `lights`.
        struct Gather<'a> {
            scene: &'a Scene,
            lights: &'a mut Lights,
            /// Per emitter: its (global) primitives, power and area.
            shapes: Vec<([Option<u32>; 2], f64, f64)>,
            first: u32,
        }
        impl Make<Flag> for Gather<'_> {
            fn make<S: Shape>(&mut self) -> bool {
                let (scene, first) = (self.scene, self.first);
                self.first += S::count(scene) as u32;
                let emitters = S::emitters(scene);
                for a in &emitters {
                    let [i, second] = a.prims.map(|p| p.map(|p| first + p));
                    let i = i.expect("an emitter has a primitive");
                    let mut scale = scene.primitive_scale(i as usize);
                    if let Some(j) = second {
                        scale = scale.max(scene.primitive_scale(j as usize));
                    }
                    let g = &a.shape;
                    let mut e = Emitter {
                        v0: g.v0,
                        e1: g.e1,
                        e2: g.e2,
                        normal: g.normal,
                        radius: g.radius,
                        parallelogram: g.parallelogram,
                        emission: a.emission.into(),
                        scale,
                        prim: f32::from_bits(i),
                        kind: S::KIND as f32,
                        ..Emitter::NONE
                    };
                    if let Some((axes, lengths)) = a.rectangle {
                        e.rectangle = 1.0;
                        self.lights.has_rectangles = true;
                        e.axes = axes.map(V3::from);
                        e.lengths = lengths;
                    }
                    self.lights.triangle.push(i);
                    self.lights.emitters.push(e);
                    self.shapes.push(([Some(i), second], a.power, a.area));
                }
                !emitters.is_empty()
            }
        }
        let mut lights = Lights::default();
        let mut gather = Gather {
            scene,
            lights: &mut lights,
            shapes: Vec::new(),
            first: 0,
        };
        let kinds = Kinds::new(&mut gather);
        let (shapes, prims) = (gather.shapes, gather.first as usize);
        lights.kinds = kinds;
        lights.mixed = Shapes::COUNT > 1 && lights.kinds.any(&mut OtherKinds);
        lights.emitter_of = vec![NOT_EMITTER; prims];
        let mut total: f64 = shapes.iter().map(|s| s.1).sum();
        let (lo, hi) = scene.bounds();
        let largest = lo.abs().max(hi.abs()).max_element();
        lights.far = 4.0 * 3f32.sqrt() * largest + 1.0;
        let r = 0.5 * f64::from((hi - lo).length()).max(1e-3);
        lights.punctual = scene
            .lights
            .iter()
            .filter_map(|l| Punctual::new(l, r))
            .collect();
        lights.suns = lights.punctual.iter().any(Punctual::is_visible_sun);
        total += lights.punctual.iter().map(|p| p.power).sum::<f64>();
        let mut environment_power = 0.0;
        if let Some(env) = &scene.environment {
            let env = EnvLight::new(env);
            if !env.is_black() {
                environment_power = 4.0 * std::f64::consts::PI * r * r * env.mean_radiance;
                environment_power = environment_power.max(f64::MIN_POSITIVE);
                total += environment_power;
            }
            lights.environment = Some(env);
        }
        let by_tree = (scene.options.light_tree).unwrap_or(shapes.len() > TREE_MIN_EMITTERS)
            && !shapes.is_empty();
        let mut sum = 0.0;
        for (k, (prims, power, area)) in shapes.iter().enumerate() {
            sum += power;
            if !by_tree {
                lights.cdf.push((sum / total) as f32);
            }
            lights.emitters[k].pdf_area = ((power / total) / area) as f32;
            lights.emitters[k].probability = (power / total) as f32;
            for prim in prims.iter().flatten() {
                lights.emitter_of[*prim as usize] = k as u32;
            }
        }
        if by_tree {
            lights.tree_probability = (sum / total) as f32;
            lights.cdf.push(lights.tree_probability);
            lights.areas = shapes.iter().map(|s| s.2 as f32).collect();
            let bounds: Vec<LightBounds> = (lights.emitters.iter().zip(&shapes))
                .map(|(e, s)| e.bounds(s.1))
                .collect();
            lights.tree = Some(LightTree::new(&bounds));
        }
        for p in &mut lights.punctual {
            sum += p.power;
            lights.cdf.push((sum / total) as f32);
            p.set_probability((p.power / total) as f32);
        }
        if environment_power > 0.0 {
            lights.cdf.push(1.0);
            lights.environment_probability = (environment_power / total) as f32;
        }
        if let Some(last) = lights.cdf.last_mut() {
            *last = 1.0;
        }
        lights.pick_in_lanes =
            lights.has_extras() && lights.cdf.len() <= 1 << 24 && sorted(&lights.cdf);
        if let ([e], None, true) = (&lights.emitters[..], &lights.tree, lights.has_extras()) {
            lights.only_8 = Some(Box::new(Emitter::splat(e)));
        }
        if let Some(e) = lights.single().filter(|_| lights.tree.is_none()).copied() {
            lights.single_8 = Some(Box::new(Emitter::splat(&e)));
            if lights.has_rectangles && !lights.mixed {
                let e = Emitter::from_floats(e.floats().map(Pair::splat));
                lights.single_16 = Some(Box::new(e));
            }
        }
        lights
    }

    /// Turn the environment, if there is one, to `rotation_deg`: the
    /// lights of the scene with its environment so turned (its power, and
    /// so every light's probability, does not depend on the rotation).
    pub fn turn_environment(&mut self, rotation_deg: f32) {
        if let Some(env) = &mut self.environment {
            env.turn(rotation_deg);
        }
    }

    /// The scene's environment, if it has one.
    #[inline]
    pub fn environment(&self) -> Option<&EnvLight> {
        self.environment.as_ref()
    }

    /// The probability with which [`Lights::sample`] picks the
    /// environment (0 without one).
    #[inline]
    pub fn environment_probability(&self) -> f32 {
        self.environment_probability
    }

    /// The density per unit solid angle with which [`Lights::sample`]
    /// draws the direction `d` from the environment (0 without one).
    #[inline]
    pub fn environment_pdf(&self, d: V3<f32>) -> f32 {
        match &self.environment {
            Some(env) if self.environment_probability > 0.0 => {
                self.environment_probability * env.pdf(d)
            }
            _ => 0.0,
        }
    }

    /// The environment's radiance from the direction `d` and the density
    /// [`environment_pdf`](Self::environment_pdf) of `d`, with `d`'s
    /// `(u, v)` computed once (`None` without an environment).
    #[inline]
    pub fn environment_radiance_and_pdf(&self, d: V3<f32>) -> Option<(V3<f32>, f32)> {
        let env = self.environment.as_ref()?;
        Some(if self.environment_probability > 0.0 {
            let (l, pdf) = env.radiance_and_pdf(d);
            (l, self.environment_probability * pdf)
        } else {
            (env.radiance(d), 0.0)
        })
    }

    /// [`Lights::sample`] in a scene with an environment or punctual
    /// lights: the running sums pick an emitter, a punctual light
    /// ([`Punctual::sample`]) or, past the last, the environment, whose
    /// direction becomes a point [`Lights::far`] away facing back (its
    /// density is by solid angle).
    fn sample_with_extras(&self, o: V3<f32>, u: [f32; 2]) -> LightPoint<f32> {
        let n = self.cdf_emitters();
        let k = self
            .cdf
            .partition_point(|&c| c <= u[0])
            .min(self.cdf.len() - 1);
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let u0 = ((u[0] - lo) / (self.cdf[k] - lo)).clamp(0.0, ONE_MINUS_EPSILON);
        if k < n {
            return match &self.tree {
                Some(tree) => self.sample_tree(tree, o, [u0, u[1]]),
                None => self.point_on(&self.emitters[k], o, [u0, u[1]]),
            };
        }
        if let Some(p) = self.punctual.get(k - n) {
            return punctual_point(p, o, [u0, u[1]], self.far);
        }
        match self
            .environment
            .as_ref()
            .and_then(|env| env.sample([u0, u[1]]))
        {
            Some(s) => LightPoint {
                point: s.dir.mul_add(self.far, o),
                normal: -s.dir,
                emission: s.radiance,
                pdf_area: 0.0,
                pdf_solid_angle: self.environment_probability * s.pdf,
                scale: 0.0,
                prim: NO_PRIM_BITS,
                delta: 0.0,
            },
            None => LightPoint::on_by_area(&Emitter::NONE, u),
        }
    }

    /// [`Lights::sample`] for up to eight shading points `o` and numbers
    /// `u`, one per lane (lanes past `lanes` get a point that carries no
    /// light), the same bits: [`pick_8`](Self::pick_8) and
    /// [`point_on`](Self::point_on) where the scene has no environment or
    /// punctual lights; else the pick among the emitters, punctual lights
    /// and environment in lanes, and the environment's directions drawn in
    /// lanes ([`EnvLight::sample_lanes`]).
    #[inline(always)]
    pub fn sample_8(&self, o: V3<f32x8>, u: [f32x8; 2], lanes: usize) -> LightPoint<f32x8> {
        if let Some(e) = &self.single_8 {
            // `pick_8`'s answer for one emitter, without the splat.
            return self.point_on(e, o, u);
        }
        if !self.has_extras() {
            let (emitters, u0) = match &self.tree {
                None => self.pick_8(u[0], lanes),
                Some(tree) => self.pick_by_tree_8(tree, o, u[0], (1 << lanes) - 1),
            };
            return self.point_on(&emitters, o, [u0, u[1]]);
        }
        if self.pick_in_lanes {
            return self.sample_extras_8(o, u, lanes);
        }
        let none = LightPoint::on_by_area(&Emitter::NONE, [0.0, 0.0]);
        let (ox, oy, oz) = (o.x.to_array(), o.y.to_array(), o.z.to_array());
        let (u0, u1) = (u[0].to_array(), u[1].to_array());
        LightPoint::lanes(std::array::from_fn(|l| {
            if l < lanes {
                self.sample(V3::new(ox[l], oy[l], oz[l]), [u0[l], u1[l]])
                    .unwrap_or(none)
            } else {
                none
            }
        }))
    }

    /// [`sample_with_extras`](Self::sample_with_extras) in lanes, the
    /// same bits in each: the running sums searched in lanes
    /// ([`pick_lanes`]); the lanes that pick the environment draw their
    /// directions in lanes ([`EnvLight::sample_lanes`]), those that pick
    /// an emitter take their points in lanes ([`point_on`](Self::point_on),
    /// the emitters gathered lane by lane where there are several, or
    /// picked by the tree), those that pick a punctual light lane by lane
    /// ([`Punctual::sample`]). Each of the three only where some lane
    /// picks it; lanes past `lanes` get a point that carries no light.
    #[inline(always)]
    fn sample_extras_8(&self, o: V3<f32x8>, u: [f32x8; 2], lanes: usize) -> LightPoint<f32x8> {
        let (k, _, u0) = pick_lanes(&self.cdf, i32x8::splat(0), self.cdf.len(), u[0]);
        let live = (1u32 << lanes) - 1;
        let n = self.cdf_emitters();
        let to_emitters = k.simd_lt(f32x8::splat(n as f32)).to_bitmask() & live;
        let past = f32x8::splat((n + self.punctual.len()) as f32);
        let to_environment = past.simd_le(k).to_bitmask() & live;
        let to_punctual = live & !to_emitters & !to_environment;
        let mut p = LightPoint::splat(&LightPoint::on_by_area(&Emitter::NONE, [0.0, 0.0]));
        if to_environment != 0 {
            let mut dark = to_environment;
            if let Some(env) = &self.environment {
                let (s, some) = env.sample_lanes([u0, u[1]]);
                let drawn = LightPoint {
                    point: s.dir.mul_add(f32x8::splat(self.far), o),
                    normal: -s.dir,
                    emission: s.radiance,
                    pdf_area: f32x8::splat(0.0),
                    pdf_solid_angle: f32x8::splat(self.environment_probability) * s.pdf,
                    scale: f32x8::splat(0.0),
                    prim: f32x8::splat(NO_PRIM_BITS),
                    delta: f32x8::splat(0.0),
                };
                let some = some.to_bitmask() & to_environment;
                p = LightPoint::select(lane_mask(some), drawn, p);
                dark &= !some;
            }
            if dark != 0 {
                // No direction: a point on no emitter, for the numbers as
                // they came.
                let none = LightPoint::on_by_area(&Emitter::splat(&Emitter::NONE), u);
                p = LightPoint::select(lane_mask(dark), none, p);
            }
        }
        if to_emitters != 0 {
            let on = match (&self.tree, &self.only_8) {
                (Some(tree), _) => {
                    let (emitters, u0) = self.pick_by_tree_8(tree, o, u0, to_emitters);
                    self.point_on(&emitters, o, [u0, u[1]])
                }
                (None, Some(e)) => self.point_on(e, o, [u0, u[1]]),
                (None, None) => {
                    let k = k.to_array();
                    let mut emitters = [&Emitter::NONE; 8];
                    for (l, e) in emitters.iter_mut().enumerate() {
                        if to_emitters & (1 << l) != 0 {
                            *e = &self.emitters[k[l] as usize];
                        }
                    }
                    self.point_on(&Emitter::lanes(emitters), o, [u0, u[1]])
                }
            };
            p = LightPoint::select(lane_mask(to_emitters), on, p);
        }
        if to_punctual != 0 {
            let (k, u0, u1) = (k.to_array(), u0.to_array(), u[1].to_array());
            let (ox, oy, oz) = (o.x.to_array(), o.y.to_array(), o.z.to_array());
            let mut points = [LightPoint::on_by_area(&Emitter::NONE, [0.0, 0.0]); 8];
            for (l, point) in points.iter_mut().enumerate() {
                if to_punctual & (1 << l) != 0 {
                    let light = &self.punctual[k[l] as usize - n];
                    let o = V3::new(ox[l], oy[l], oz[l]);
                    *point = punctual_point(light, o, [u0[l], u1[l]], self.far);
                }
            }
            p = LightPoint::select(lane_mask(to_punctual), LightPoint::lanes(points), p);
        }
        p
    }

    /// [`sample_8`](Self::sample_8) for two groups of eight lanes at once
    /// (`o[k]`, `u[k]` and `lanes[k]` are group `k`'s): where the scene's
    /// one emitter is a rectangle, both groups' points are computed side by
    /// side as one [`Pair`] (each operation on the two groups back to back,
    /// so that the long chains of divisions, square roots and arc cosines
    /// of the one overlap those of the other); else group by group. The
    /// same bits as two calls of [`sample_8`](Self::sample_8).
    #[inline(always)]
    pub fn sample_16(
        &self,
        o: [V3<f32x8>; 2],
        u: [[f32x8; 2]; 2],
        lanes: [usize; 2],
    ) -> [LightPoint<f32x8>; 2] {
        let Some(e) = &self.single_16 else {
            return [
                self.sample_8(o[0], u[0], lanes[0]),
                self.sample_8(o[1], u[1], lanes[1]),
            ];
        };
        let pair = |a: f32x8, b: f32x8| Pair([a, b]);
        let o2 = V3::new(
            pair(o[0].x, o[1].x),
            pair(o[0].y, o[1].y),
            pair(o[0].z, o[1].z),
        );
        let u2 = [pair(u[0][0], u[1][0]), pair(u[0][1], u[1][1])];
        self.point_on(e, o2, u2).halves()
    }

    /// The emitter of a one-emitter scene, if it has exactly one.
    #[inline]
    pub fn single(&self) -> Option<&Emitter> {
        match self.emitters.as_slice() {
            [e] if !self.has_extras() => Some(e),
            _ => None,
        }
    }

    /// Whether the scene has nothing to sample: no emitter, no
    /// environment with light.
    pub fn is_empty(&self) -> bool {
        self.triangle.is_empty() && !self.has_extras()
    }

    /// Whether the scene has an environment with light, or punctual
    /// lights: lights sampled after the emitters, with running sums of
    /// their own after the emitters'. (Read from the sums, not from the
    /// environment's probability, which a scene of overflowing size makes
    /// NaN: [`pick`](Self::pick) must never see a sum past the emitters.)
    #[inline]
    fn has_extras(&self) -> bool {
        self.cdf.len() > self.cdf_emitters()
    }

    /// How many entries of the running sums are the emitters': one (the
    /// tree's) where they are picked by a tree, else one each.
    #[inline]
    fn cdf_emitters(&self) -> usize {
        match self.tree {
            Some(_) => 1,
            None => self.emitters.len(),
        }
    }

    /// The light tree, where the scene has one (more than
    /// [`TREE_MIN_EMITTERS`] emitters).
    pub fn tree(&self) -> Option<&LightTree> {
        self.tree.as_ref()
    }

    /// A point on the emitter the tree picks for the shading point `o`
    /// with `u[0]` ([`LightTree::sample`], which stretches `u[0]` back over
    /// `[0, 1)`), by [`point_on`](Self::point_on) with the emitter's
    /// probability there; a point that carries no light where no emitter
    /// faces `o`.
    #[inline]
    fn sample_tree(&self, tree: &LightTree, o: V3<f32>, u: [f32; 2]) -> LightPoint<f32> {
        match tree.sample(Vec3::from(o), u[0]) {
            Some((k, pmf, u0)) => {
                let e = self.picked_with(k as usize, self.tree_probability * pmf);
                self.point_on(&e, o, [u0, u[1]])
            }
            None => LightPoint::on_by_area(&Emitter::NONE, u),
        }
    }

    /// [`sample_tree`](Self::sample_tree)'s picks for the lanes `l` of
    /// eight shading points `o` and numbers `u0` whose bit `1 << l` is set
    /// in `lanes`, lane by lane: the emitters (with their probabilities
    /// there; [`Emitter::NONE`] where none faces the point, and in the
    /// other lanes) and the stretched numbers.
    #[inline(always)]
    fn pick_by_tree_8(
        &self,
        tree: &LightTree,
        o: V3<f32x8>,
        u0: f32x8,
        lanes: u32,
    ) -> (Emitter<f32x8>, f32x8) {
        let (ox, oy, oz) = (o.x.to_array(), o.y.to_array(), o.z.to_array());
        let mut u = u0.to_array();
        let mut picked = [Emitter::NONE; 8];
        for l in (0..8).filter(|l| lanes & (1 << l) != 0) {
            if let Some((k, pmf, u_l)) = tree.sample(Vec3::new(ox[l], oy[l], oz[l]), u[l]) {
                picked[l] = self.picked_with(k as usize, self.tree_probability * pmf);
                u[l] = u_l;
            }
        }
        (Emitter::lanes(picked.each_ref()), f32x8::from(u))
    }

    /// Emitter `k` picked with probability `probability` (a tree's pick,
    /// which depends on the shading point): its densities scaled to it.
    #[inline]
    fn picked_with(&self, k: usize, probability: f32) -> Emitter {
        Emitter {
            probability,
            pdf_area: probability / self.areas[k],
            ..self.emitters[k]
        }
    }

    /// The probability that [`Lights::sample`] for the shading point `o`
    /// picks emitter `k` (by the tree where there is one, else by power).
    #[inline]
    pub fn emitter_probability(&self, k: usize, o: V3<f32>) -> f32 {
        match &self.tree {
            Some(tree) => self.tree_probability * tree.pmf(Vec3::from(o), k as u32),
            None => self.emitters[k].probability,
        }
    }

    /// Whether rays that leave the scene can see something: an
    /// environment, or a sun with a cone.
    #[inline]
    pub fn sees_escapes(&self) -> bool {
        self.environment.is_some() || self.suns
    }

    /// The suns whose cones hold the direction `d` of a ray that left the
    /// scene: each one's radiance and the density with which
    /// [`Lights::sample`] draws `d` from it ([`Punctual::seen`]).
    #[inline]
    pub fn suns_seen(&self, d: V3<f32>) -> impl Iterator<Item = (V3<f32>, f32)> + '_ {
        let suns = if self.suns { &self.punctual[..] } else { &[] };
        suns.iter().filter_map(move |p| p.seen(d))
    }

    /// The scene's sun, point and spot lights that send light.
    pub fn punctual(&self) -> &[Punctual] {
        &self.punctual
    }

    /// Number of emitters (not counting an environment).
    pub fn len(&self) -> usize {
        self.triangle.len()
    }

    /// The emitter (its index, `0..len()`) that primitive `prim` belongs
    /// to, if it emits.
    pub fn emitter_of(&self, prim: u32) -> Option<usize> {
        match self.emitter_of.get(prim as usize) {
            Some(&NOT_EMITTER) | None => None,
            Some(&k) => Some(k as usize),
        }
    }

    /// The emitter that `u0` in `[0, 1)` chooses, by power, and `u0`
    /// stretched back to `[0, 1)` over that emitter's share of the unit
    /// interval ([`Emitter::NONE`] when the scene has none). A 2D point
    /// `(u0, u1)` thus picks an emitter and a point on it: stratified
    /// points stay stratified over all the emitters together, and a
    /// sample needs no number of its own to pick with.
    #[inline]
    pub fn pick(&self, u0: f32) -> (&Emitter, f32) {
        let k = match self.cdf.len() {
            0 => return (&Emitter::NONE, u0),
            1 => return (&self.emitters[0], u0),
            // The first emitter whose running sum exceeds `u0`.
            n => self.cdf.partition_point(|&c| c <= u0).min(n - 1),
        };
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let u = (u0 - lo) / (self.cdf[k] - lo);
        (&self.emitters[k], u.clamp(0.0, ONE_MINUS_EPSILON))
    }

    /// A point on an emitter for the shading point `o`: `u[0]` chooses
    /// the emitter by power (and is reused, [`pick`](Self::pick)), `u`
    /// places the point on it ([`LightPoint::on`]). `None` when the scene
    /// has no emitter.
    #[inline]
    pub fn sample(&self, o: V3<f32>, u: [f32; 2]) -> Option<LightPoint<f32>> {
        if self.is_empty() {
            return None;
        }
        if self.has_extras() || self.tree.is_some() {
            return Some(self.sample_with_extras(o, u));
        }
        let (emitter, u0) = self.pick(u[0]);
        Some(self.point_on(emitter, o, [u0, u[1]]))
    }

    /// [`pick`](Self::pick) for the first `lanes` of eight numbers: the
    /// emitters, one per lane (lanes past `lanes` get [`Emitter::NONE`],
    /// or the scene's one emitter), and the stretched numbers.
    #[inline(always)]
    pub fn pick_8(&self, u0: f32x8, lanes: usize) -> (Emitter<f32x8>, f32x8) {
        if let Some(e) = self.single() {
            return (Emitter::splat(e), u0);
        }
        let mut u = u0.to_array();
        let mut emitters = [&Emitter::NONE; 8];
        for l in 0..lanes {
            (emitters[l], u[l]) = self.pick(u[l]);
        }
        (Emitter::lanes(emitters), f32x8::from(u))
    }

    /// The point on `emitter` (one lane or eight) for the shading point
    /// `o` and the numbers `u`: [`LightPoint::on`] (where the scene has
    /// rectangle emitters) or [`LightPoint::on_by_area`], and where the
    /// scene has emitters of other kinds than the first, each lane of such
    /// a kind the point its kind samples ([`Shape::sample_area`]).
    #[inline(always)]
    pub fn point_on<R: Real>(&self, emitter: &Emitter<R>, o: V3<R>, u: [R; 2]) -> LightPoint<R> {
        let p = if self.has_rectangles {
            LightPoint::on(emitter, o, u)
        } else {
            LightPoint::on_by_area(emitter, u)
        };
        if !self.mixed {
            return p;
        }
        let mut by_kind = ByKind { emitter, u, p };
        self.kinds.any(&mut by_kind);
        by_kind.p
    }

    /// The density per unit area with which [`Lights::sample`] picks a
    /// point on primitive `triangle` (triangles, then spheres; 0 for one
    /// that does not emit) when it samples by area.
    #[inline]
    pub fn pdf_area(&self, triangle: u32) -> f32 {
        match self.emitter_of[triangle as usize] {
            NOT_EMITTER => 0.0,
            k => self.emitters[k as usize].pdf_area,
        }
    }

    /// The density per unit solid angle at `o` with which
    /// [`Lights::sample`] for the shading point `o` finds the point at
    /// distance `t` on primitive `triangle`, whose front faces `o` at
    /// cosine `cos_light` (0 for a primitive that does not emit): the same
    /// density the light sample computes, by solid angle or by area.
    #[inline]
    pub fn pdf_solid_angle(&self, triangle: u32, o: V3<f32>, t: f32, cos_light: f32) -> f32 {
        let picked;
        let e = match (self.emitter_of[triangle as usize], &self.tree) {
            (NOT_EMITTER, _) => return 0.0,
            (k, None) => &self.emitters[k as usize],
            (k, Some(_)) => {
                let k = k as usize;
                picked = self.picked_with(k, self.emitter_probability(k, o));
                &picked
            }
        };
        let by_area = e.pdf_area * (t * t) / cos_light;
        if e.rectangle == 0.0 {
            return by_area;
        }
        let rect = SphericalRectangle::new(e, o);
        if rect.used(e) {
            e.probability / rect.solid_angle
        } else {
            by_area
        }
    }
}

/// Sixteen lanes as two groups of eight side by side: each operation is
/// [`f32x8`]'s on the first group, then on the second. Each lane computes
/// what it would as an `f32x8` lane (and so as an `f32`), bit for bit; the
/// point is the order of the instructions, which puts two independent
/// dependency chains next to each other for the processor to overlap
/// ([`Lights::sample_16`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair(pub [f32x8; 2]);

macro_rules! pair_binop {
    ($tr:ident, $f:ident) => {
        impl std::ops::$tr for Pair {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                let ([a, b], [c, d]) = (self.0, o.0);
                Pair([std::ops::$tr::$f(a, c), std::ops::$tr::$f(b, d)])
            }
        }
    };
}
pair_binop!(Add, add);
pair_binop!(Sub, sub);
pair_binop!(Mul, mul);
pair_binop!(Div, div);
pair_binop!(BitAnd, bitand);
pair_binop!(BitOr, bitor);

impl std::ops::Neg for Pair {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Pair(self.0.map(|a| -a))
    }
}

impl Pair {
    /// `f` on each group.
    #[inline(always)]
    fn each(self, f: impl Fn(f32x8) -> f32x8) -> Self {
        let [a, b] = self.0;
        Pair([f(a), f(b)])
    }

    /// `f` on each group of `self` and `o`.
    #[inline(always)]
    fn each2(self, o: Self, f: impl Fn(f32x8, f32x8) -> f32x8) -> Self {
        let ([a, b], [c, d]) = (self.0, o.0);
        Pair([f(a, c), f(b, d)])
    }
}

impl Real for Pair {
    /// Per group, [`f32x8`]'s mask.
    type Mask = Pair;
    type Id = [u32; 16];
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Pair([f32x8::splat(x); 2])
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        let ([x, y], [a0, a1], [b0, b1]) = (self.0, a.0, b.0);
        Pair([Real::mul_add(x, a0, b0), Real::mul_add(y, a1, b1)])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.each(Real::sqrt)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.each(Real::abs)
    }
    #[inline(always)]
    fn round_ties_even(self) -> Self {
        self.each(Real::round_ties_even)
    }
    #[inline(always)]
    fn lt(self, rhs: Self) -> Pair {
        self.each2(rhs, Real::lt)
    }
    #[inline(always)]
    fn le(self, rhs: Self) -> Pair {
        self.each2(rhs, Real::le)
    }
    #[inline(always)]
    fn eq(self, rhs: Self) -> Pair {
        self.each2(rhs, Real::eq)
    }
    #[inline(always)]
    fn ne(self, rhs: Self) -> Pair {
        self.each2(rhs, Real::ne)
    }
    #[inline(always)]
    fn select(mask: Pair, a: Self, b: Self) -> Self {
        let ([m0, m1], [a0, a1], [b0, b1]) = (mask.0, a.0, b.0);
        Pair([
            <f32x8 as Real>::select(m0, a0, b0),
            <f32x8 as Real>::select(m1, a1, b1),
        ])
    }
}

impl LightPoint<Pair> {
    /// The two groups' points.
    #[inline(always)]
    fn halves(self) -> [LightPoint<f32x8>; 2] {
        let half = |k: usize| {
            let v = |v: V3<Pair>| V3::new(v.x.0[k], v.y.0[k], v.z.0[k]);
            LightPoint {
                point: v(self.point),
                normal: v(self.normal),
                emission: v(self.emission),
                pdf_area: self.pdf_area.0[k],
                pdf_solid_angle: self.pdf_solid_angle.0[k],
                scale: self.scale.0[k],
                prim: self.prim.0[k],
                delta: self.delta.0[k],
            }
        };
        [half(0), half(1)]
    }
}

impl<R: Real> LightPoint<R> {
    /// Lane-wise `if mask { a } else { b }`.
    #[inline(always)]
    fn select(mask: R::Mask, a: Self, b: Self) -> Self {
        Self {
            point: V3::select(mask, a.point, b.point),
            normal: V3::select(mask, a.normal, b.normal),
            emission: V3::select(mask, a.emission, b.emission),
            pdf_area: R::select(mask, a.pdf_area, b.pdf_area),
            pdf_solid_angle: R::select(mask, a.pdf_solid_angle, b.pdf_solid_angle),
            scale: R::select(mask, a.scale, b.scale),
            prim: R::select(mask, a.prim, b.prim),
            delta: R::select(mask, a.delta, b.delta),
        }
    }
}

impl LightPoint<f32x8> {
    /// Eight points, one per lane.
    #[inline(always)]
    fn lanes(points: [LightPoint<f32>; 8]) -> Self {
        let lane = |f: &dyn Fn(&LightPoint<f32>) -> f32| f32x8::from(points.each_ref().map(f));
        let lane3 = |f: &dyn Fn(&LightPoint<f32>) -> V3<f32>| {
            V3::new(lane(&|p| f(p).x), lane(&|p| f(p).y), lane(&|p| f(p).z))
        };
        LightPoint {
            point: lane3(&|p| p.point),
            normal: lane3(&|p| p.normal),
            emission: lane3(&|p| p.emission),
            pdf_area: lane(&|p| p.pdf_area),
            pdf_solid_angle: lane(&|p| p.pdf_solid_angle),
            scale: lane(&|p| p.scale),
            prim: lane(&|p| p.prim),
            delta: lane(&|p| p.delta),
        }
    }

    /// One point in all eight lanes.
    #[inline(always)]
    fn splat(p: &LightPoint<f32>) -> Self {
        let v = |v: V3<f32>| V3::new(f32x8::splat(v.x), f32x8::splat(v.y), f32x8::splat(v.z));
        LightPoint {
            point: v(p.point),
            normal: v(p.normal),
            emission: v(p.emission),
            pdf_area: f32x8::splat(p.pdf_area),
            pdf_solid_angle: f32x8::splat(p.pdf_solid_angle),
            scale: f32x8::splat(p.scale),
            prim: f32x8::splat(p.prim),
            delta: f32x8::splat(p.delta),
        }
    }
}

/// The mask of the lanes `l` whose bit `1 << l` is set in `bits`.
#[inline(always)]
fn lane_mask(bits: u32) -> f32x8 {
    let lane = i32x8::from([1, 2, 4, 8, 16, 32, 64, 128]);
    let set = (lane & i32x8::splat(bits as i32)).simd_ne(i32x8::splat(0));
    bytemuck::cast(set)
}

/// The point that the punctual light `p` gives the shading point `o` for
/// the numbers `u` ([`Punctual::sample`]), as [`Lights::sample`] returns
/// it: a point [`Lights::far`] away for a sun, its density by solid angle.
#[inline]
fn punctual_point(p: &Punctual, o: V3<f32>, u: [f32; 2], far: f32) -> LightPoint<f32> {
    let s = p.sample(o, u, far);
    LightPoint {
        point: s.point,
        normal: s.normal,
        emission: s.emission,
        pdf_area: 0.0,
        pdf_solid_angle: s.pdf,
        scale: 0.0,
        prim: NO_PRIM_BITS,
        delta: if s.delta { 1.0 } else { 0.0 },
    }
}

/// The power heuristic (β = 2) weight of a strategy of density `a` against
/// one of density `b`: `a² / (a² + b²)`, 1 when `b` is 0.
#[inline(always)]
pub fn power_heuristic<R: Real>(a: R, b: R) -> R {
    let (a2, b2) = (a * a, b * b);
    R::select(b2.eq(R::splat(0.0)), R::splat(1.0), a2 / (a2 + b2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampler::PathRng;
    use glam::Vec3;

    #[test]
    fn square_to_triangle_is_uniform_on_the_triangle() {
        // Points land inside; each of the 4 sub-triangles of the midpoint
        // subdivision gets a quarter of them (within 4 sigma).
        let mut rng = PathRng::new(1, 2, 3);
        let n = 200_000;
        let mut counts = [0u32; 4];
        for _ in 0..n {
            let [b1, b2] = square_to_triangle([rng.next_f32(), rng.next_f32()]);
            let b0 = 1.0 - b1 - b2;
            assert!(b0 >= 0.0 && b1 >= 0.0 && b2 >= 0.0, "{b0} {b1} {b2}");
            let k = if b0 > 0.5 {
                0
            } else if b1 > 0.5 {
                1
            } else if b2 > 0.5 {
                2
            } else {
                3
            };
            counts[k] += 1;
        }
        let (mean, sigma) = (n as f64 / 4.0, (n as f64 * 0.25 * 0.75).sqrt());
        for c in counts {
            assert!((c as f64 - mean).abs() < 4.0 * sigma, "{counts:?}");
        }
    }

    /// A scene whose size overflows `f32` (two tiny triangles at ±3·10³⁸,
    /// nothing emitting) under a sky: the sky's power is infinite and its
    /// probability NaN. Drawing a light point gives NaN numbers (samples
    /// that the film refuses), never a panic: this panicked in
    /// `pick` (`emitters[0]` of none) when the extras were told by the
    /// probability (found by tests/fuzz.rs's `hostile_gltf`).
    #[test]
    fn a_sky_over_a_scene_of_overflowing_size_is_sampled_without_panic() {
        let mut scene = Scene::cornell();
        for m in &mut scene.materials {
            m.emission = Vec3::ZERO;
        }
        for (k, x) in [(0, 3e38f32), (1, -3e38)] {
            let t = &mut scene.triangles[k];
            t.v = [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x, 1.0, 0.0),
                Vec3::new(x, 0.0, 1.0),
            ];
        }
        let sky = crate::scene::environment::EnvSource::Constant([1.0; 3]);
        scene.environment =
            Some(crate::scene::environment::Environment::load(&sky, 1.0, 0.0, true).unwrap());
        let lights = Lights::new(&scene);
        let o = V3::new(f32x8::splat(0.5), f32x8::splat(0.5), f32x8::splat(0.5));
        let _ = lights.sample_8(o, [f32x8::splat(0.3), f32x8::splat(0.6)], 8);
        let _ = lights.sample(V3::new(0.5, 0.5, 0.5), [0.3, 0.6]);
        assert!(lights.environment_probability.is_nan());
        assert!(!lights.is_empty() && lights.emitters.is_empty());
    }

    /// The Cornell box with its light's second triangle given its own
    /// material, emitting `factor` times as much: two emitters.
    fn cornell_two_lights(factor: f32) -> Scene {
        let mut scene = Scene::cornell();
        let lights: Vec<usize> = (0..scene.triangles.len())
            .filter(|&i| {
                scene.materials[scene.triangles[i].material as usize].emission != Vec3::ZERO
            })
            .collect();
        let mut brighter = scene.materials[scene.triangles[lights[1]].material as usize].clone();
        brighter.emission *= factor;
        scene.materials.push(brighter);
        scene.triangles[lights[1]].material = scene.materials.len() as u32 - 1;
        scene
    }

    #[test]
    fn emitters_are_picked_by_power() {
        // Two triangles of equal area, the second three times as bright:
        // picked a quarter and three quarters of the time.
        let scene = cornell_two_lights(3.0);
        let lights = Lights::new(&scene);
        assert_eq!(lights.len(), 2);
        let area = |e: &Emitter| 0.5 * Vec3::from(e.e1).cross(e.e2.into()).length();
        for (k, (e, want)) in lights.emitters.iter().zip([0.25, 0.75]).enumerate() {
            assert!((e.probability - want).abs() < 1e-6, "{}", e.probability);
            let p = lights.pdf_area(lights.triangle[k]) * area(e);
            assert!((p - want).abs() < 1e-6, "{p}");
            assert_eq!(e.pdf_area, lights.pdf_area(lights.triangle[k]));
            assert_eq!(e.parallelogram, 0.0);
        }
        // Picks follow the running sums of the powers, and stretch the
        // number back over the emitter's share.
        let pick = |u: f32| {
            let (e, u) = lights.pick(u);
            (std::ptr::eq(e, &lights.emitters[0]), u)
        };
        assert_eq!(pick(0.0), (true, 0.0));
        assert_eq!(pick(0.125), (true, 0.5));
        assert_eq!(pick(0.625), (false, 0.5));
        let (first, u) = pick(0.999_999_9);
        assert!(!first && u < 1.0 && u > 0.999_99);
        // Non-emitters have density 0; samples lie on the light's plane.
        assert_eq!(lights.pdf_area(0), 0.0);
        let y = scene.triangles[lights.triangle[0] as usize].v[0].y;
        let mut rng = PathRng::new(4, 4, 4);
        let o = V3::new(0.1, 0.5, 0.2);
        for _ in 0..1000 {
            let s = lights.sample(o, [rng.next_f32(), rng.next_f32()]).unwrap();
            assert!((s.point.y - y).abs() < 1e-6);
            assert!([10.0, 30.0].contains(&s.emission.x));
            assert_eq!(s.pdf_solid_angle, 0.0, "triangles are sampled by area");
        }
        // No emitter, no sample.
        let mut dark = scene.clone();
        dark.materials
            .iter_mut()
            .for_each(|m| m.emission = Vec3::ZERO);
        assert!(Lights::new(&dark).sample(o, [0.5, 0.5]).is_none());
    }

    #[test]
    fn two_triangles_that_make_a_rectangle_are_one_emitter() {
        let scene = Scene::cornell();
        let lights = Lights::new(&scene);
        assert_eq!(lights.len(), 1);
        let e = lights.single().unwrap();
        assert_eq!(
            (e.parallelogram, e.rectangle, e.probability),
            (1.0, 1.0, 1.0)
        );
        // Both triangles of the light look up the square's density.
        let light: Vec<u32> = (0..scene.triangles.len() as u32)
            .filter(|&i| lights.pdf_area(i) > 0.0)
            .collect();
        assert_eq!(light.len(), 2);
        let area = Vec3::from(e.e1).cross(e.e2.into()).length();
        for &i in &light {
            assert!((lights.pdf_area(i) * area - 1.0).abs() < 1e-6);
        }
        // Points sampled by area (from a point that sees the square at a
        // grazing angle) cover the square, corner to corner, uniformly:
        // each quarter gets a quarter.
        let o = V3::new(5.0, -0.99, 0.0);
        let mut rng = PathRng::new(5, 5, 5);
        let mut quarters = [0u32; 4];
        let n = 40_000;
        for _ in 0..n {
            let s = lights.sample(o, [rng.next_f32(), rng.next_f32()]).unwrap();
            assert_eq!(s.pdf_solid_angle, 0.0, "seen too small: by area");
            let q = Vec3::from(s.point) - Vec3::from(e.v0);
            let (e1, e2) = (Vec3::from(e.e1), Vec3::from(e.e2));
            let (a, b) = (
                q.dot(e1) / e1.length_squared(),
                q.dot(e2) / e2.length_squared(),
            );
            assert!((-1e-6..=1.0 + 1e-6).contains(&a) && (-1e-6..=1.0 + 1e-6).contains(&b));
            quarters[(a >= 0.5) as usize * 2 + (b >= 0.5) as usize] += 1;
        }
        let sigma = (n as f64 * 0.25 * 0.75).sqrt();
        for c in quarters {
            assert!(
                (c as f64 - n as f64 / 4.0).abs() < 4.0 * sigma,
                "{quarters:?}"
            );
        }
        // A kite (the second triangle's far corner moved) is two emitters.
        let mut kite = scene.clone();
        kite.triangles[light[1] as usize]
            .v
            .iter_mut()
            .for_each(|v| {
                if v.x > 0.4 && v.z > 0.4 {
                    v.x += 0.1;
                }
            });
        assert_eq!(Lights::new(&kite).len(), 2);
        // So are two triangles of different materials.
        assert_eq!(Lights::new(&cornell_two_lights(1.0)).len(), 2);
    }

    /// The solid angle of the Cornell box's light seen from `o`, by
    /// integrating `cos θ_l / r²` over it on a fine grid (midpoint rule).
    fn solid_angle_by_quadrature(e: &Emitter, o: Vec3) -> f64 {
        let m = 400;
        let (v0, e1, e2, n) = (
            Vec3::from(e.v0).as_dvec3(),
            Vec3::from(e.e1).as_dvec3(),
            Vec3::from(e.e2).as_dvec3(),
            Vec3::from(e.normal).as_dvec3(),
        );
        let da = e1.cross(e2).length() / (m * m) as f64;
        let mut sum = 0.0;
        for i in 0..m {
            for j in 0..m {
                let p =
                    v0 + e1 * ((i as f64 + 0.5) / m as f64) + e2 * ((j as f64 + 0.5) / m as f64);
                let d = p - o.as_dvec3();
                sum += n.dot(-d).abs() / d.length().powi(3) * da;
            }
        }
        sum
    }

    #[test]
    fn the_spherical_rectangle_has_the_rectangles_solid_angle() {
        let lights = Lights::new(&Scene::cornell());
        let e = lights.single().unwrap();
        for o in [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-0.9, 0.2, 0.7),
            Vec3::new(0.95, -0.8, -0.95),
            Vec3::new(0.3, -0.9, 0.1),
        ] {
            let s = SphericalRectangle::new(e, V3::from(o)).solid_angle as f64;
            let q = solid_angle_by_quadrature(e, o);
            assert!((s - q).abs() < 1e-4 * q + 1e-6, "from {o}: {s} vs {q}");
        }
    }

    /// χ² of points sampled on the Cornell box's light from `o` against
    /// uniform density by solid angle, over a 6×6 grid of cells on the
    /// light (each cell's expected share is its solid angle over the
    /// light's), and its degrees of freedom.
    fn chi2_by_solid_angle(o: Vec3, point: impl Fn([f32; 2]) -> V3<f32>) -> (f64, f64) {
        let lights = Lights::new(&Scene::cornell());
        let e = *lights.single().unwrap();
        let cells = 6;
        let total = SphericalRectangle::new(&e, V3::from(o)).solid_angle as f64;
        let mut expected = vec![0.0; cells * cells];
        for i in 0..cells {
            for j in 0..cells {
                let (e1, e2) = (
                    Vec3::from(e.e1) / cells as f32,
                    Vec3::from(e.e2) / cells as f32,
                );
                let cell = Emitter {
                    v0: (Vec3::from(e.v0) + e1 * i as f32 + e2 * j as f32).into(),
                    e1: e1.into(),
                    e2: e2.into(),
                    ..e
                };
                expected[i * cells + j] = solid_angle_by_quadrature(&cell, o) / total;
            }
        }
        let n = 200_000;
        let mut counts = vec![0u32; cells * cells];
        let mut rng = PathRng::new(9, 9, 9);
        let (e1, e2) = (Vec3::from(e.e1), Vec3::from(e.e2));
        for _ in 0..n {
            let p = Vec3::from(point([rng.next_f32(), rng.next_f32()])) - Vec3::from(e.v0);
            let cell = |f: f32| (f * cells as f32).clamp(0.0, cells as f32 - 1.0) as usize;
            let (a, b) = (
                cell(p.dot(e1) / e1.length_squared()),
                cell(p.dot(e2) / e2.length_squared()),
            );
            counts[a * cells + b] += 1;
        }
        let chi2 = counts
            .iter()
            .zip(&expected)
            .map(|(&c, &p)| (c as f64 - n as f64 * p).powi(2) / (n as f64 * p))
            .sum();
        (chi2, (cells * cells - 1) as f64)
    }

    #[test]
    fn spherical_rectangle_points_are_uniform_by_solid_angle() {
        // χ² with 35 degrees of freedom: mean 35, sd 8.4; 80 is far out in
        // the tail (p ≈ 2e-5).
        let lights = Lights::new(&Scene::cornell());
        let e = *lights.single().unwrap();
        for o in [Vec3::new(0.0, 0.9, 0.0), Vec3::new(-0.9, -0.7, 0.8)] {
            let rect = SphericalRectangle::new(&e, V3::from(o));
            let (chi2, dof) = chi2_by_solid_angle(o, |u| rect.sample(&e, u));
            assert!(chi2 < 80.0, "from {o}: chi2 {chi2} ({dof} dof)");
            // The same test rejects points uniform by area (a sampler
            // whose pdf would be wrong by the solid angle's variation).
            let (chi2, _) =
                chi2_by_solid_angle(o, |u| e.e1.mul_add(u[0], e.e2.mul_add(u[1], e.v0)));
            assert!(chi2 > 80.0, "from {o}: area sampling passed, chi2 {chi2}");
        }
    }

    #[test]
    fn the_density_of_a_hit_is_the_density_of_the_light_sample() {
        // What the MIS weight of a scattered ray that hits the light looks
        // up equals what the light sample that found the same point had.
        let lights = Lights::new(&Scene::cornell());
        let prim = (0..64).find(|&i| lights.pdf_area(i) > 0.0).unwrap();
        let mut rng = PathRng::new(6, 6, 6);
        for o in [
            V3::new(0.0, 0.9, 0.0),
            V3::new(-0.9, -0.98, 0.8),
            V3::new(5.0, -0.99, 0.0),
        ] {
            for _ in 0..100 {
                let s = lights.sample(o, [rng.next_f32(), rng.next_f32()]).unwrap();
                let to = Vec3::from(s.point) - Vec3::from(o);
                let cos = -Vec3::from(s.normal).dot(to.normalize());
                let by_sample = if s.pdf_solid_angle > 0.0 {
                    s.pdf_solid_angle
                } else {
                    s.pdf_area * to.length_squared() / cos
                };
                let by_hit = lights.pdf_solid_angle(prim, o, to.length(), cos);
                assert!(
                    (by_sample - by_hit).abs() <= 1e-5 * by_hit,
                    "{by_sample} {by_hit}"
                );
            }
        }
    }

    #[test]
    fn eight_lanes_sample_the_points_one_lane_does() {
        for scene in [Scene::cornell(), cornell_two_lights(3.0)] {
            let lights = Lights::new(&scene);
            let mut rng = PathRng::new(8, 8, 8);
            for _ in 0..1000 {
                let u: [[f32; 2]; 8] = std::array::from_fn(|_| [rng.next_f32(), rng.next_f32()]);
                let o: [Vec3; 8] = std::array::from_fn(|_| {
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0
                });
                let o8 = V3::new(
                    f32x8::from(o.map(|o| o.x)),
                    f32x8::from(o.map(|o| o.y)),
                    f32x8::from(o.map(|o| o.z)),
                );
                let (e, u0) = lights.pick_8(f32x8::from(u.map(|u| u[0])), 8);
                let p8 = LightPoint::on(&e, o8, [u0, f32x8::from(u.map(|u| u[1]))]);
                for (l, &u) in u.iter().enumerate() {
                    let p = lights.sample(V3::from(o[l]), u).unwrap();
                    let lane = |v: f32x8| v.to_array()[l].to_bits();
                    assert_eq!(
                        [p.point.x, p.point.y, p.point.z].map(f32::to_bits),
                        [lane(p8.point.x), lane(p8.point.y), lane(p8.point.z)]
                    );
                    assert_eq!(p.pdf_area.to_bits(), lane(p8.pdf_area));
                    assert_eq!(p.pdf_solid_angle.to_bits(), lane(p8.pdf_solid_angle));
                }
            }
        }
    }

    /// Sixteen lanes side by side ([`Lights::sample_16`]: one rectangle,
    /// as a [`Pair`]; else two groups of eight) sample the points one lane
    /// does, bit for bit, in both groups, however many lanes the second
    /// has.
    #[test]
    fn sixteen_lanes_sample_the_points_one_lane_does() {
        for (scene, paired) in [(Scene::cornell(), true), (cornell_two_lights(3.0), false)] {
            let lights = Lights::new(&scene);
            assert_eq!(lights.single_16.is_some(), paired);
            let mut rng = PathRng::new(16, 16, 16);
            let mut mismatches = 0;
            for round in 0..1000 {
                let u: [[f32; 2]; 16] = std::array::from_fn(|_| [rng.next_f32(), rng.next_f32()]);
                let o: [Vec3; 16] = std::array::from_fn(|_| {
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0
                });
                let col = |k: usize, f: &dyn Fn(usize) -> f32| {
                    f32x8::from(std::array::from_fn::<f32, 8, _>(|l| f(8 * k + l)))
                };
                let o8 = |k| {
                    V3::new(
                        col(k, &|l| o[l].x),
                        col(k, &|l| o[l].y),
                        col(k, &|l| o[l].z),
                    )
                };
                let u8 = |k| [col(k, &|l| u[l][0]), col(k, &|l| u[l][1])];
                let lanes = [8, 1 + round % 8];
                let p16 = lights.sample_16([o8(0), o8(1)], [u8(0), u8(1)], lanes);
                for l in 0..8 + lanes[1] {
                    let p = lights.sample(V3::from(o[l]), u[l]).unwrap();
                    let q = &p16[l / 8];
                    let lane = |v: f32x8| v.to_array()[l % 8].to_bits();
                    let bits = |v: V3<f32>| [v.x, v.y, v.z].map(f32::to_bits);
                    let lane3 = |v: V3<f32x8>| [lane(v.x), lane(v.y), lane(v.z)];
                    let same = bits(p.point) == lane3(q.point)
                        && bits(p.normal) == lane3(q.normal)
                        && bits(p.emission) == lane3(q.emission)
                        && p.pdf_area.to_bits() == lane(q.pdf_area)
                        && p.pdf_solid_angle.to_bits() == lane(q.pdf_solid_angle)
                        && p.prim.to_bits() == lane(q.prim);
                    mismatches += usize::from(!same);
                }
            }
            assert_eq!(mismatches, 0, "lanes that differ from one lane's point");
        }
    }

    /// Emitters of two kinds (the Cornell box's quad light and two
    /// emissive spheres) sampled eight lanes at a time, the lanes' kinds
    /// mixed: each lane's point is the one lane's, bit for bit, and lies
    /// on its own emitter (on a sphere's surface; in a triangle's plane),
    /// with the normal of its kind there.
    #[test]
    fn mixed_kinds_sample_each_lanes_own_emitter() {
        let mut scene = Scene::cornell();
        let lamp = (scene.triangles.iter())
            .map(|t| t.material)
            .find(|&m| scene.materials[m as usize].emission != Vec3::ZERO)
            .expect("the Cornell box has a light");
        let spheres = [
            (Vec3::new(0.2, -0.3, 0.1), 0.2),
            (Vec3::new(-0.5, 0.4, -0.2), 0.1),
        ];
        for (center, radius) in spheres {
            scene.spheres.push(crate::scene::Sphere {
                center,
                radius,
                material: lamp,
            });
        }
        let lights = Lights::new(&scene);
        assert!(
            lights.mixed && lights.len() == 3,
            "{} emitters",
            lights.len()
        );
        let mut rng = PathRng::new(9, 9, 9);
        let mut on_sphere = 0;
        for _ in 0..1000 {
            let u: [[f32; 2]; 8] = std::array::from_fn(|_| [rng.next_f32(), rng.next_f32()]);
            let o: [Vec3; 8] = std::array::from_fn(|_| {
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 1.6 - 0.8
            });
            let col = |f: &dyn Fn(usize) -> f32| f32x8::from(std::array::from_fn::<f32, 8, _>(f));
            let o8 = V3::new(col(&|l| o[l].x), col(&|l| o[l].y), col(&|l| o[l].z));
            let u8 = [col(&|l| u[l][0]), col(&|l| u[l][1])];
            let p8 = lights.sample_8(o8, u8, 8);
            for (l, &u) in u.iter().enumerate() {
                let p = lights.sample(V3::from(o[l]), u).unwrap();
                let lane = |v: f32x8| v.to_array()[l].to_bits();
                let bits = |v: V3<f32>| [v.x, v.y, v.z].map(f32::to_bits);
                let lane3 = |v: V3<f32x8>| [lane(v.x), lane(v.y), lane(v.z)];
                assert_eq!(bits(p.point), lane3(p8.point), "lane {l}");
                assert_eq!(bits(p.normal), lane3(p8.normal), "lane {l}");
                let (point, normal) = (Vec3::from(p.point), Vec3::from(p.normal));
                let prim = p.prim.to_bits() as usize;
                match prim.checked_sub(scene.triangles.len()) {
                    Some(k) => {
                        on_sphere += 1;
                        let (c, r) = spheres[k];
                        assert!(
                            ((point - c).length() - r).abs() < 1e-5,
                            "{point} off sphere {k}"
                        );
                        assert!(
                            (normal - (point - c) / r).length() < 1e-4,
                            "normal {normal}"
                        );
                    }
                    None => {
                        let t = &scene.triangles[prim];
                        assert!(
                            t.normal.dot(point - t.v[0]).abs() < 1e-5,
                            "{point} off the light"
                        );
                        assert_eq!(normal, t.normal);
                    }
                }
            }
        }
        assert!(
            (1000..7000).contains(&on_sphere),
            "{on_sphere} of 8000 on spheres"
        );
    }

    #[test]
    fn power_heuristic_weights_sum_to_one() {
        for (a, b) in [(1.0, 1.0), (2.0, 0.5), (1e-3, 7.0)] {
            let w = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((w - 1.0).abs() < 1e-6);
        }
        assert_eq!(power_heuristic(3.0, 0.0), 1.0);
    }
}
