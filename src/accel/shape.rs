//! Shape kinds behind one trait, [`Shape`], and the machinery of the one
//! list of the kinds there are ([`Kinds`], made by the `kinds!` line of
//! `accel/mod.rs`).
//!
//! A kind is everything the renderer needs of a primitive, in one place:
//! how the scene lists it ([`Shape::in_scene`], [`Shape::materials`]), its
//! box ([`Shape::bounds`]), its SIMD pack and kernel ([`Shape::Pack`],
//! [`ShapePack`]: closest hit and any hit of one ray against
//! [`Lanes::LANES`] primitives), its scalar kernel
//! ([`Shape::intersect`], for brute force), the surface at a hit
//! ([`Shape::front_normal`] from its [`Shape::Surface`] data) and, for
//! emitters, area sampling ([`Shape::sample_area`]) with the area and
//! geometry the light sampler needs ([`Shape::emitters`]).
//!
//! The hierarchy (`bvh/`), the scene's tables and the lights hold one
//! value per kind in a [`Kinds`] (of the type a [`Family`] says) and go
//! through the kinds with a visitor ([`Visit`], [`VisitOne`], [`Make`]),
//! generic over the kind: every call is monomorphised, no `dyn`. Kinds are
//! numbered in the list's order; primitive indices follow it too (the
//! first kind's primitives, then the second's, ...).
//!
//! Adding a kind: its file (the type, its [`Shape`] implementation and its
//! pack), and in `accel/mod.rs` its `mod` line and its entry in the
//! `kinds!` list; in the scene layer, its type and list in `Scene` (with
//! its arms of the per-primitive methods), a `SceneBuilder` method and its
//! front-end table (`docs/architecture.md` counts the files).

pub use super::Kinds;
use crate::accel::hit::{Hit, HitFilter, KeepAll, PackHits};
use crate::accel::simd::Lanes;
use crate::math::{Real, V3};
use crate::scene::Scene;
use glam::{Vec3, Vec3A};
use std::fmt::Debug;

/// A kind of primitive: see the module documentation.
pub trait Shape: Kind + Copy + Debug + PartialEq + Send + Sync + 'static {
    /// The kind's pack of [`Lanes::LANES`] primitives (8 or 16).
    type Pack<R: Lanes>: ShapePack<R>;

    /// What the surface at a hit needs of one primitive (a triangle: its
    /// front normal; a sphere: its center).
    type Surface: Copy + Debug + Send + Sync + 'static;

    /// The scene's primitives of this kind, in index order, as the kernels
    /// want them.
    fn in_scene(scene: &Scene) -> Vec<Self>;

    /// The material of each of the scene's primitives of this kind, in
    /// index order.
    fn materials(scene: &Scene) -> Vec<u32>;

    /// The primitive's box (minimum and maximum corners), or `None` where
    /// it has none (a non-finite coordinate): such a primitive is tested
    /// by every ray before the walk, as brute force would.
    fn bounds(&self) -> Option<(Vec3A, Vec3A)>;

    /// Up to [`Lanes::LANES`] primitives, each with the (global) index a
    /// hit reports, in one pack; unused lanes hit nothing and carry index
    /// `u32::MAX`.
    fn pack<R: Lanes>(shapes: &[(u32, Self)]) -> Self::Pack<R>;

    /// The scalar kernel: whether the ray `o + t·d` hits the primitive at
    /// a `t > t_min`, and that `t` — the same bits as any lane of its pack
    /// kernel.
    fn intersect(&self, o: V3<f32>, d: V3<f32>, t_min: f32) -> (bool, f32);

    /// The [`Shape::Surface`] data of the scene's primitives of this
    /// kind, in index order.
    fn surfaces(scene: &Scene) -> Vec<Self::Surface>;

    /// The front normal where it is the same at every point of the
    /// primitive (a triangle's), else `None` (it is computed at each hit:
    /// [`Shape::front_normal`]).
    fn flat_normal(surface: &Self::Surface) -> Option<Vec3>;

    /// The front (outward) unit normal where the ray `o + t·d` hits the
    /// primitive of data `surface`.
    fn front_normal(surface: &Self::Surface, o: V3<f32>, d: V3<f32>, t: f32) -> V3<f32>;

    /// The number of the scene's primitives of this kind.
    fn count(scene: &Scene) -> usize;

    /// The scene's emitters of this kind (its primitives whose material
    /// emits, of positive finite power), in index order, as the light
    /// sampler takes them.
    fn emitters(scene: &Scene) -> Vec<AreaEmitter>;

    /// A point of an emitter of this kind, uniform by area, for the unit
    /// square's point `u`: the point and the emitter's front normal there,
    /// one lane or eight (the same bits).
    fn sample_area<R: Real>(e: &AreaShape<R>, u: [R; 2]) -> (V3<R>, V3<R>);
}

/// An emitter's geometry as [`Shape::sample_area`] reads it (one lane or
/// eight); each kind says what its fields mean (a triangle: a vertex and
/// two edges; a sphere: its center and radius). Unused fields are zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AreaShape<R> {
    /// A point (a triangle's vertex 0, a parallelogram's corner, a
    /// sphere's center).
    pub v0: V3<R>,
    /// A first edge or axis.
    pub e1: V3<R>,
    /// A second edge or axis.
    pub e2: V3<R>,
    /// The front unit normal, where it is the same everywhere.
    pub normal: V3<R>,
    /// A radius.
    pub radius: R,
    /// 1 for a parallelogram (the points `v0 + a e1 + b e2`, `a`, `b` in
    /// `[0, 1]`), else 0.
    pub parallelogram: R,
}

/// One emitter of a kind, as [`Shape::emitters`] lists it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AreaEmitter {
    /// Its geometry.
    pub shape: AreaShape<f32>,
    /// Its primitives (indices among the kind's): one, or two (two
    /// triangles that make a parallelogram); the first names it.
    pub prims: [Option<u32>; 2],
    /// Its area.
    pub area: f64,
    /// Its power (`area × mean emitted radiance`).
    pub power: f64,
    /// The radiance it emits towards its front.
    pub emission: Vec3,
    /// A rectangle's unit edges and their lengths (a parallelogram with
    /// square corners: sampled by solid angle where it looks large).
    pub rectangle: Option<([Vec3; 2], [f32; 2])>,
}

/// A kind's pack of primitives, as the hierarchy's queries test it.
pub trait ShapePack<R: Lanes>: Copy + Debug + Send + Sync {
    /// Test one ray (broadcast to every lane) against the pack's
    /// primitives, keeping in `best` each lane's smallest `(t, index)`
    /// ([`PackHits::keep`]). `IN_INDEX_ORDER`: the caller tests packs in
    /// increasing index order (then an equal `t` never wins).
    fn intersect<const IN_INDEX_ORDER: bool>(
        &self,
        o: &V3<R>,
        d: &V3<R>,
        t_min: R,
        best: &mut PackHits<R>,
    );

    /// Whether a primitive of the pack lies at `t_min < t < t_max`: the
    /// same test, lane for lane, as `intersect` with `best.t = t_max`.
    fn occludes(&self, o: &V3<R>, d: &V3<R>, t_min: R, t_max: R) -> bool;
}

/// A kind's place in the list of kinds: its number and its entry in a
/// [`Kinds`] (implemented by the `kinds!` list).
pub trait Kind: Sized {
    /// The kind's number: its position in the list (a leaf of the
    /// hierarchy carries it in two bits; 3 is no leaf, so at most three
    /// kinds).
    const KIND: u32;
    /// Its entry of `k`.
    fn of<F: Family>(k: &Kinds<F>) -> &F::Of<Self>
    where
        Self: Shape;
}

/// A type per kind: what a [`Kinds`] holds for kind `S`.
pub trait Family {
    /// The type for kind `S`.
    type Of<S: Shape>;
}

/// A visit of every kind in order ([`Kinds::any`]).
pub trait Visit<F: Family> {
    /// Visit kind `S`'s entry; `true` stops the visit.
    fn visit<S: Shape>(&mut self, entry: &F::Of<S>) -> bool;
}

/// A visit of one kind, chosen by its number ([`Kinds::by_kind`]).
pub trait VisitOne<F: Family> {
    /// What the visit returns.
    type Out;
    /// Visit kind `S`'s entry.
    fn visit<S: Shape>(self, entry: &F::Of<S>) -> Self::Out;
}

/// How to make each kind's entry ([`Kinds::new`]).
pub trait Make<F: Family> {
    /// Kind `S`'s entry.
    fn make<S: Shape>(&mut self) -> F::Of<S>;
}

/// Defines [`Kinds`] from the list of kinds, `number field: Type, ...`
/// (invoked once, in `accel/mod.rs`).
macro_rules! kinds {
    ($($kind:literal $field:ident: $ty:ty),* $(,)?) => {
        /// One value per shape kind (of the type `F` says), in the order
        /// of the kinds.
        pub struct Kinds<F: $crate::accel::shape::Family> {
            $(
                #[doc = concat!("Kind ", stringify!($kind), ": `", stringify!($ty), "`.")]
                pub $field: F::Of<$ty>,
            )*
        }

        $(
            impl $crate::accel::shape::Kind for $ty {
                const KIND: u32 = $kind;
                #[inline(always)]
                fn of<F: $crate::accel::shape::Family>(k: &Kinds<F>) -> &F::Of<Self> {
                    &k.$field
                }
            }
        )*

        impl<F: $crate::accel::shape::Family> Kinds<F> {
            /// The number of kinds.
            pub const COUNT: usize = [$($kind),*].len();

            /// Each kind's entry, made by `m` in the kinds' order.
            #[inline(always)]
            pub fn new(m: &mut impl $crate::accel::shape::Make<F>) -> Self {
                Self { $($field: m.make::<$ty>(),)* }
            }

            /// Visit every kind in order until `v` returns `true`; whether
            /// it did.
            #[inline(always)]
            pub fn any(&self, v: &mut impl $crate::accel::shape::Visit<F>) -> bool {
                $(v.visit::<$ty>(&self.$field))||*
            }

            /// Visit kind number `kind` (`None` for no kind).
            #[inline(always)]
            pub fn by_kind<V: $crate::accel::shape::VisitOne<F>>(&self, kind: u32, v: V) -> Option<V::Out> {
                match kind {
                    $($kind => Some(v.visit::<$ty>(&self.$field)),)*
                    _ => None,
                }
            }
        }

        impl<F: $crate::accel::shape::Family> Clone for Kinds<F>
        where
            $(F::Of<$ty>: Clone,)*
        {
            fn clone(&self) -> Self {
                Self { $($field: self.$field.clone(),)* }
            }
        }

        impl<F: $crate::accel::shape::Family> std::fmt::Debug for Kinds<F>
        where
            $(F::Of<$ty>: std::fmt::Debug,)*
        {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.debug_struct("Kinds")$(.field(stringify!($field), &self.$field))*.finish()
            }
        }

        impl<F: $crate::accel::shape::Family> Default for Kinds<F>
        where
            $(F::Of<$ty>: Default,)*
        {
            fn default() -> Self {
                Self { $($field: Default::default(),)* }
            }
        }
    };
}

pub(crate) use kinds;

const _: () = assert!(
    Kinds::<Owned>::COUNT <= 3,
    "a leaf has two bits for its kind"
);

/// Each kind's primitives, borrowed: `Kinds<Slices<'a>>` ([`Shapes`]).
pub struct Slices<'a>(std::marker::PhantomData<&'a ()>);

impl<'a> Family for Slices<'a> {
    type Of<S: Shape> = &'a [S];
}

/// Each kind's primitives, owned.
pub struct Owned;

impl Family for Owned {
    type Of<S: Shape> = Vec<S>;
}

/// The primitives of every kind, borrowed: what a hierarchy is built over.
pub type Shapes<'a> = Kinds<Slices<'a>>;

/// The primitives of every kind, owned.
pub type OwnedShapes = Kinds<Owned>;

impl OwnedShapes {
    /// The scene's primitives of every kind ([`Shape::in_scene`]).
    pub fn of_scene(scene: &Scene) -> Self {
        struct FromScene<'a>(&'a Scene);
        impl Make<Owned> for FromScene<'_> {
            fn make<S: Shape>(&mut self) -> Vec<S> {
                S::in_scene(self.0)
            }
        }
        Self::new(&mut FromScene(scene))
    }

    /// The lists, borrowed.
    pub fn as_shapes(&self) -> Shapes<'_> {
        struct Borrow<'a>(&'a OwnedShapes);
        impl<'a> Make<Slices<'a>> for Borrow<'a> {
            fn make<S: Shape>(&mut self) -> &'a [S] {
                S::of(self.0)
            }
        }
        Shapes::new(&mut Borrow(self))
    }
}

impl<'a> Shapes<'a> {
    /// The number of primitives of every kind together.
    pub fn len(&self) -> usize {
        struct Count(usize);
        impl<'a> Visit<Slices<'a>> for Count {
            fn visit<S: Shape>(&mut self, list: &&'a [S]) -> bool {
                self.0 += list.len();
                false
            }
        }
        let mut c = Count(0);
        self.any(&mut c);
        c.0
    }

    /// Whether there are no primitives at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Each kind's number of primitives, in the kinds' order.
    pub fn counts(&self) -> [usize; Shapes::COUNT] {
        struct Counts([usize; Shapes::COUNT]);
        impl<'a> Visit<Slices<'a>> for Counts {
            fn visit<S: Shape>(&mut self, list: &&'a [S]) -> bool {
                self.0[S::KIND as usize] = list.len();
                false
            }
        }
        let mut c = Counts([0; Shapes::COUNT]);
        self.any(&mut c);
        c.0
    }
}

/// The index of kind `S`'s first primitive among all primitives, given
/// each kind's count ([`Shapes::counts`]): the counts of the kinds before
/// it, summed.
#[inline(always)]
pub fn first_of<S: Shape>(counts: &[usize; Shapes::COUNT]) -> usize {
    counts[..S::KIND as usize].iter().sum()
}

/// The primitive of global index `prim`: its kind's number and its index
/// among that kind's, given each kind's first index (`firsts`, increasing,
/// the first 0).
#[inline(always)]
pub fn kind_of(prim: usize, firsts: &[usize; Shapes::COUNT]) -> (u32, usize) {
    let mut k = Shapes::COUNT - 1;
    while k > 0 && prim < firsts[k] {
        k -= 1;
    }
    (k as u32, prim - firsts[k])
}

/// Scalar brute force over every kind's primitives, in index order: the
/// plainest closest-hit query, the reference the hierarchy matches bit for
/// bit. The answer is the smallest `(t, index)` with `t_min < t < t_max`
/// (a primitive is kept only when strictly closer: on equal `t` the lower
/// index, which came first, stays).
pub fn closest_hit_brute_force_shapes(
    shapes: &Shapes<'_>,
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<Hit> {
    closest_hit_brute_force_filtered(shapes, o, d, (t_min, t_max), &KeepAll)
}

/// [`closest_hit_brute_force_shapes`] among the hits that `filter` does
/// not let through ([`HitFilter`]): the smallest `(t, index)` of those,
/// what [`Bvh::closest_hit_filtered`](crate::accel::bvh::Bvh::closest_hit_filtered)
/// returns bit for bit.
pub fn closest_hit_brute_force_filtered<F: HitFilter>(
    shapes: &Shapes<'_>,
    o: Vec3,
    d: Vec3,
    (t_min, t_max): (f32, f32),
    filter: &F,
) -> Option<Hit> {
    struct Brute<'f, F> {
        o: V3<f32>,
        d: V3<f32>,
        t_min: f32,
        t_max: f32,
        first: u32,
        best: Option<Hit>,
        filter: &'f F,
    }
    impl<'a, F: HitFilter> Visit<Slices<'a>> for Brute<'_, F> {
        fn visit<S: Shape>(&mut self, list: &&'a [S]) -> bool {
            for (j, s) in list.iter().enumerate() {
                let limit = self.best.map_or(self.t_max, |h| h.t);
                let (hit, t) = s.intersect(self.o, self.d, self.t_min);
                let prim = self.first + j as u32;
                if hit && t < limit && !(self.filter.may_pass(prim) && self.filter.passes(prim, t))
                {
                    self.best = Some(Hit { triangle: prim, t });
                }
            }
            self.first += list.len() as u32;
            false
        }
    }
    let mut b = Brute {
        o: V3::from(o),
        d: V3::from(d),
        t_min,
        t_max,
        first: 0,
        best: None,
        filter,
    };
    shapes.any(&mut b);
    b.best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A global primitive index names its kind and its index among the
    /// kind's, also where a kind has no primitives.
    #[test]
    fn kind_of_splits_global_indices_by_kind() {
        let n = Shapes::COUNT;
        let firsts = |counts: [usize; Shapes::COUNT]| -> [usize; Shapes::COUNT] {
            std::array::from_fn(|k| counts[..k].iter().sum())
        };
        for counts in [[5, 3], [0, 4], [7, 0], [1, 1]] {
            let mut counts_n = [0; Shapes::COUNT];
            counts_n[..2].copy_from_slice(&counts);
            let f = firsts(counts_n);
            let mut want = Vec::new();
            for (k, &c) in counts_n.iter().enumerate() {
                want.extend((0..c).map(|i| (k as u32, i)));
            }
            let got: Vec<(u32, usize)> = (0..want.len()).map(|p| kind_of(p, &f)).collect();
            assert_eq!(got, want, "counts {counts:?} of {n} kinds");
        }
    }
}
