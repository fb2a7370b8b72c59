//! The scene as the engines read it: per-primitive and per-material
//! columns, gathered 1 or 8 lanes at a time, and the surface at a hit
//! ([`SurfaceHit`]) made from them. Primitives are numbered as hits
//! number them: the kinds one after the other, in the order of
//! [`Kinds`] (the triangles, then the spheres). Each kind's normal at a
//! hit comes from its [`Shape`] implementation; the tables name no kind
//! but triangles, whose vertex attributes (normals, texture coordinates,
//! colours, tangents) they keep.

use crate::accel::hit::HitFilter;
use crate::accel::shape::{Family, Kinds, Make, Shape, Shapes, VisitOne, kind_of};
use crate::accel::simd::prefetch_lines;
use crate::accel::triangle::hit_point;
use crate::integrator::bsdf::surface::Texels;
use crate::integrator::bsdf::{Constants, Surface};
use crate::integrator::surface::SurfaceHit;
use crate::integrator::texture::sample_lanes;
use crate::math::{V3, Vec3x8};
use crate::scene::material::Coverage;
use crate::scene::texture::{Texture, TextureRef};
use crate::scene::{
    Material, Model, Scene, TriangleUv, barycentric, interpolate_normal, interpolate_uv,
};
use std::f32::consts::PI;
use std::sync::Arc;
use wide::f32x8;

/// Tables of rows above this many bytes are [`Tables::prefetch_rows`]'s
/// business (they outgrow the L2 cache).
const BIG_TABLE: usize = 256 << 10;

/// Shading data, one column per field.
pub struct Tables {
    /// Material index of each primitive.
    pub material_of: Vec<u32>,
    /// Each kind's first primitive index.
    firsts: [usize; Shapes::COUNT],
    /// Each kind's [`Shape::Surface`] data, per primitive of the kind.
    surfaces: Kinds<SurfacesOf>,
    /// Whether some primitive's front normal is not flat
    /// ([`Shape::flat_normal`]): computed at each hit.
    curved: bool,
    /// Emitted radiance of each material.
    pub emission: Vec<[f32; 3]>,
    /// Per primitive, what a bounce reads of it, in one row of eight
    /// (front normal x, y, z — zero where not flat, as a sphere's —, the
    /// diffuse BRDF
    /// `reflectance / π` of its material, R, G, B, the material's index
    /// (its bits), and its [`Scene::primitive_scale`]): eight
    /// rows load as eight vectors and transpose into columns
    /// ([`Tables::rows_8`]), cheaper than 48 loads lane by lane. A row is
    /// aligned to half a cache line, so it lies in one.
    rows: Vec<f32x8>,
    /// The rows are too many for the caches: a bounce asks for them ahead
    /// ([`Tables::prefetch_rows`]).
    big: bool,
    /// Whether each primitive's material emits, from the first emitting
    /// primitive (`emitting_first`) to the last, and one more entry (false)
    /// that every other primitive and every miss reads
    /// ([`Tables::emits`]): in a big scene lit by a few triangles, a table
    /// that stays in the L1 cache.
    emitting: Vec<bool>,
    emitting_first: u32,
    /// Scattering model of each material.
    pub model: Vec<Model>,
    /// Each material's constant scattering parameters, per model
    /// ([`Constants`]).
    constants: Constants,
    /// Each material's albedo AOV (its reflectance clamped to [0, 1]),
    /// RGB, indexed by material.
    pub albedo: Vec<[f32; 3]>,
    /// Smooth triangles' vertices and vertex normals, per triangle (empty
    /// when the scene has none: [`Scene::vertex_normals`]).
    pub smooth: Vec<([glam::Vec3; 3], [glam::Vec3; 3])>,
    /// Triangles' vertices and vertex texture coordinates (sets 0 and 1),
    /// per triangle (empty when the scene has none:
    /// [`Scene::texturing`]).
    pub uv: Vec<([glam::Vec3; 3], TriangleUv)>,
    /// Whether some material absorbs light inside it
    /// ([`Material::absorbs`]): paths are then attenuated on the way out
    /// ([`Tables::transmittance`]).
    absorbing: bool,
    /// The materials, for the textured ones' lookups
    /// ([`Tables::scattering`]).
    materials: Vec<Material>,
    /// Per model (in the order of [`Model::ALL`]), whether some surface of
    /// it is textured (a material with [`Maps`](crate::scene::material::Maps),
    /// or vertex colours): its parameters are looked up per hit.
    textured: [bool; Model::ALL.len()],
    /// Per model, which of the [`scattering_maps`] some material of it
    /// has (bit `k`: map `k`): the maps [`Tables::surfaces_at`] reads.
    maps_of_model: [u8; Model::ALL.len()],
    /// Triangles' vertices and vertex colours ([`Scene::texturing`]), or
    /// empty.
    colours: Vec<([glam::Vec3; 3], [[f32; 4]; 3])>,
    /// The images the materials' maps read.
    textures: Arc<Vec<Texture>>,
    /// Whether some material is not [`Coverage::Opaque`]: hits are then
    /// tested for cut-outs ([`Tables::passes`]).
    cutouts: bool,
    /// Per material: whether it is not [`Coverage::Opaque`] (hits on it
    /// may let rays through).
    see_through: Vec<bool>,
    /// Triangles' vertex tangents ([`Scene::texturing`]), or empty (no
    /// normal textures to read).
    tangents: Vec<[[f32; 4]; 3]>,
    /// Whether some material has a normal texture and some triangle
    /// tangents: shading normals are then bent per hit
    /// ([`Tables::shading_normal`]).
    normal_maps: bool,
    /// Whether some material's emission is textured
    /// ([`Maps::emissive`](crate::scene::material::Maps::emissive)): its
    /// radiance is looked up per hit and per light sample
    /// ([`Tables::emission_at`]).
    emissive_maps: bool,
    /// Each primitive's object id ([`crate::scene::Objects`]): read only
    /// by the object_id AOV.
    objects: Vec<u32>,
}

impl Tables {
    /// The tables of `scene`.
    pub fn new(scene: &Scene) -> Self {
        let kinds = KindTables::of(scene);
        let materials = kinds.materials;
        let brdf = |m: &u32| scene.materials[*m as usize].reflectance / PI;
        let emits: Vec<bool> = (materials.iter())
            .map(|&m| scene.materials[m as usize].emission != glam::Vec3::ZERO)
            .collect();
        let span = match (
            emits.iter().position(|&e| e),
            emits.iter().rposition(|&e| e),
        ) {
            (Some(a), Some(b)) => a..b + 1,
            _ => 0..0,
        };
        Self {
            firsts: kinds.firsts,
            surfaces: kinds.surfaces,
            curved: kinds.curved,
            emission: scene
                .materials
                .iter()
                .map(|m| m.emission.to_array())
                .collect(),
            model: scene.materials.iter().map(|m| m.model).collect(),
            emitting: emits[span.clone()].iter().copied().chain([false]).collect(),
            emitting_first: span.start as u32,
            rows: (materials.iter().enumerate())
                .map(|(p, m)| {
                    let n = kinds.flat_normals[p];
                    let f = brdf(m);
                    let m = f32::from_bits(*m);
                    let s = scene.primitive_scale(p);
                    f32x8::new([n.x, n.y, n.z, f.x, f.y, f.z, m, s])
                })
                .collect(),
            big: materials.len() * size_of::<f32x8>() > BIG_TABLE,
            material_of: materials,
            constants: Constants::new(&scene.materials),
            albedo: (scene.materials.iter())
                .map(|m| {
                    m.reflectance
                        .clamp(glam::Vec3::ZERO, glam::Vec3::ONE)
                        .to_array()
                })
                .collect(),
            smooth: if scene.vertex_normals.is_empty() {
                Vec::new()
            } else {
                (scene.triangles.iter())
                    .zip(&scene.vertex_normals)
                    .map(|(t, n)| (t.v, *n))
                    .collect()
            },
            uv: (scene.triangles.iter())
                .zip(&scene.texturing.uv)
                .map(|(t, uv)| (t.v, *uv))
                .collect(),
            absorbing: scene.materials.iter().any(Material::absorbs),
            materials: scene.materials.clone(),
            textured: Model::ALL.map(|model| {
                (scene.materials.iter()).any(|m| {
                    m.model == model && (!m.maps.is_empty() || !scene.texturing.colours.is_empty())
                })
            }),
            maps_of_model: Model::ALL.map(|model| {
                (scene.materials.iter())
                    .filter(|m| m.model == model)
                    .flat_map(|m| scattering_maps(m).into_iter().enumerate())
                    .fold(0, |bits, (k, map)| bits | (u8::from(map.is_some()) << k))
            }),
            colours: (scene.triangles.iter())
                .zip(&scene.texturing.colours)
                .map(|(t, c)| (t.v, *c))
                .collect(),
            textures: scene.texturing.textures.clone(),
            cutouts: (scene.materials.iter()).any(|m| m.coverage != Coverage::Opaque),
            see_through: (scene.materials.iter())
                .map(|m| m.coverage != Coverage::Opaque)
                .collect(),
            emissive_maps: (scene.materials.iter()).any(|m| m.maps.emissive.is_some()),
            objects: scene.objects.of_primitive.clone(),
            tangents: match (scene.materials.iter()).any(|m| m.maps.normal.is_some()) {
                true => scene.texturing.tangents.clone(),
                false => Vec::new(),
            },
            normal_maps: !scene.texturing.tangents.is_empty()
                && !scene.texturing.uv.is_empty()
                && (scene.materials.iter()).any(|m| m.maps.normal.is_some()),
        }
    }

    /// The id of the object primitive `prim` belongs to (1 for a primitive
    /// of no listed object).
    #[inline]
    pub fn object_of(&self, prim: u32) -> u32 {
        self.objects.get(prim as usize).copied().unwrap_or(1)
    }

    /// Whether the surface hit `hit` (a primitive, or a miss) emits: a
    /// lookup without a branch.
    #[inline(always)]
    pub fn emits(&self, hit: u32) -> bool {
        // Below the span, the difference wraps to a huge index, as a miss
        // (`NO_PRIM`) does: both read the last entry.
        let k = hit.wrapping_sub(self.emitting_first) as usize;
        self.emitting[k.min(self.emitting.len() - 1)]
    }

    /// The surface where the ray `(o, d)` hits primitive `prim` at
    /// distance `t`: its kind's front normal there
    /// ([`Shape::front_normal`]: a triangle's normal, a sphere's radius
    /// through the hit) and, if smooth, a triangle's interpolated vertex
    /// normals.
    #[inline(always)]
    pub fn surface(&self, prim: usize, (o, d): (V3<f32>, V3<f32>), t: f32) -> SurfaceHit<f32> {
        let ng = self.front_normal(prim, o, d, t);
        let shading = self.has_smooth().then(|| {
            let p = hit_point(o, d, t);
            self.shading_normal(prim, ng, p).unwrap_or(ng)
        });
        let ids = (prim as u32, self.material_of[prim]);
        let scale = self.rows[prim].to_array()[7];
        let mut s = SurfaceHit::new((o, d), t, ids, (ng, scale), shading);
        if self.has_uv() {
            s.uv = self.texcoords(prim, s.p);
        }
        s
    }

    /// [`surface`](Self::surface) of eight lanes (`prims` may repeat a
    /// live lane's primitive in lanes past the live rows).
    #[inline(always)]
    pub fn surface_8(
        &self,
        prims: &[usize; 8],
        (o, d): (Vec3x8, Vec3x8),
        t: f32x8,
    ) -> SurfaceHit<f32x8> {
        let [nx, ny, nz, _, _, _, material, scale] = self.rows_8(prims);
        let ng = self.curved_normals(prims, V3::new(nx, ny, nz), (o, d), t);
        let shading = self.has_smooth().then(|| {
            let p = hit_point(o, d, t);
            self.shading_normals(prims, ng, p)
        });
        let ids = (
            prims.map(|p| p as u32),
            material.to_array().map(f32::to_bits),
        );
        let mut s = SurfaceHit::new((o, d), t, ids, (ng, scale), shading);
        if self.has_uv() {
            let p = lanes3(s.p);
            let uv: [[[f32; 2]; 2]; 8] = std::array::from_fn(|l| self.texcoords(prims[l], p[l]));
            s.uv = [0, 1].map(|set| [0, 1].map(|c| f32x8::new(uv.map(|l| l[set][c]))));
        }
        s
    }

    /// Whether some triangles have texture coordinates.
    #[inline(always)]
    pub fn has_uv(&self) -> bool {
        !self.uv.is_empty()
    }

    /// The texture coordinates (sets 0 and 1) of primitive `prim` at its
    /// point `p`: a triangle's vertex coordinates interpolated at the
    /// barycentric coordinates of `p` (as [`Scene::texcoords`] has them),
    /// zero for the other kinds.
    #[inline(always)]
    pub fn texcoords(&self, prim: usize, p: V3<f32>) -> [[f32; 2]; 2] {
        match self.uv.get(prim) {
            Some((v, uv)) => {
                let b = barycentric(*v, glam::Vec3::from(p));
                uv.map(|set| interpolate_uv(set, b))
            }
            None => [[0.0; 2]; 2],
        }
    }

    /// The front (outward) unit normal of primitive `prim` where the ray
    /// `o + t·d` hits it: its kind's [`Shape::front_normal`] (a triangle's
    /// own normal, or a sphere's radius through the hit, as the reference
    /// tracer has it).
    #[inline(always)]
    pub fn front_normal(&self, prim: usize, o: V3<f32>, d: V3<f32>, t: f32) -> V3<f32> {
        let (kind, i) = kind_of(prim, &self.firsts);
        let visit = FrontNormal { i, o, d, t };
        let n = self.surfaces.by_kind(kind, visit);
        n.expect("a primitive is of a kind")
    }

    /// The front normals `n` of eight lanes (from the rows: flat ones),
    /// with the lanes whose primitives' normals are not flat replaced by
    /// theirs ([`front_normal`](Self::front_normal)).
    #[inline(always)]
    fn curved_normals(
        &self,
        prims: &[usize; 8],
        n: Vec3x8,
        (o, d): (Vec3x8, Vec3x8),
        t: f32x8,
    ) -> Vec3x8 {
        if !self.curved {
            return n;
        }
        let (o, d, t) = (lanes3(o), lanes3(d), t.to_array());
        replace_lanes(n, |l| {
            let (kind, i) = kind_of(prims[l], &self.firsts);
            let visit = CurvedNormal(FrontNormal {
                i,
                o: o[l],
                d: d[l],
                t: t[l],
            });
            self.surfaces.by_kind(kind, visit).flatten()
        })
    }

    /// In a big scene, ask the memory system for the rows of the primitives
    /// `hits[range]` (misses are skipped), which a bounce will read soon;
    /// in a small one, nothing.
    #[inline(always)]
    pub fn prefetch_rows(&self, hits: &[u32], range: std::ops::Range<usize>) {
        if self.big {
            for &p in &hits[range] {
                if let Some(row) = self.rows.get(p as usize) {
                    prefetch_lines(row, 1);
                }
            }
        }
    }

    /// The [`rows`](Self::rows) of eight primitives, as eight columns.
    #[inline(always)]
    fn rows_8(&self, prims: &[usize; 8]) -> [f32x8; 8] {
        let row = |l: usize| self.rows[prims[l]];
        f32x8::transpose([
            row(0),
            row(1),
            row(2),
            row(3),
            row(4),
            row(5),
            row(6),
            row(7),
        ])
    }

    /// Whether some triangles have a shading normal of their own: vertex
    /// normals, or a normal texture.
    #[inline(always)]
    pub fn has_smooth(&self) -> bool {
        !self.smooth.is_empty() || self.normal_maps
    }

    /// The front shading normals of eight lanes at their hit points `p`:
    /// for smooth triangles their vertex normals interpolated by the
    /// scalar [`interpolate_normal`] (as the reference tracer has them,
    /// through [`Scene::shading_normal`]), else the front normals `front`.
    #[inline(always)]
    pub fn shading_normals(&self, prims: &[usize; 8], front: Vec3x8, p: Vec3x8) -> Vec3x8 {
        if !self.has_smooth() {
            return front;
        }
        let (f, p) = (lanes3(front), lanes3(p));
        if !self.normal_maps {
            return replace_lanes(front, |l| self.vertex_normal(prims[l], f[l], p[l]));
        }
        crate::integrator::texture::timed(|| {
            // Each lane's `shading_normal`, its normal texture read for
            // the eight lanes at once (`lookup_8`): the same bits.
            let smooth: [_; 8] = std::array::from_fn(|l| self.vertex_normal(prims[l], f[l], p[l]));
            let frames: [_; 8] = std::array::from_fn(|l| {
                self.normal_frame(prims[l], smooth[l].unwrap_or(f[l]), p[l])
            });
            let maps = frames.each_ref().map(|b| b.as_ref().map(|b| b.map));
            let uv = frames
                .each_ref()
                .map(|b| b.as_ref().map_or([[0.0; 2]; 2], |b| b.uv));
            let texels = self.lookup_8(&maps, &uv);
            replace_lanes(front, |l| {
                let bent = frames[l].as_ref().and_then(|b| b.bend(texels[l], f[l]));
                bent.or(smooth[l])
            })
        })
    }

    /// The front shading normal of primitive `prim` at its point `p`, for
    /// one lane: a smooth triangle's vertex normals interpolated by
    /// [`interpolate_normal`] (as [`Scene::shading_normal`] has it), or
    /// `None` (the front normal `front` shades).
    ///
    /// Where the triangle's material has a normal texture and the triangle
    /// tangents, that normal (or `front`) bent by the texture
    /// (`mapped_normal`).
    #[inline(always)]
    pub fn shading_normal(&self, prim: usize, front: V3<f32>, p: V3<f32>) -> Option<V3<f32>> {
        let smooth = self.vertex_normal(prim, front, p);
        if !self.normal_maps {
            return smooth;
        }
        self.mapped_normal(prim, (front, smooth.unwrap_or(front)), p)
            .or(smooth)
    }

    /// The normal texture of primitive `prim`'s material, read at its
    /// point `p`, bending the front shading normal `n` (a triangle's
    /// geometric front normal `front`, or its interpolated vertex
    /// normals), as glTF 2.0 defines it: the texel's RGB `c` (linear) is
    /// the tangent-space normal `(2c − 1)` with X and Y times the texture's
    /// `scale`, in the frame of the tangent `t` (the vertex tangents
    /// interpolated at `p`, made orthogonal to `n`), the bitangent
    /// `w · (n × t)` and `n`; normalised. `None` where there is nothing to
    /// bend (no texture, no tangents) or the result is degenerate or turns
    /// below the geometric surface.
    #[inline]
    fn mapped_normal(
        &self,
        prim: usize,
        (front, n): (V3<f32>, V3<f32>),
        p: V3<f32>,
    ) -> Option<V3<f32>> {
        let b = self.normal_frame(prim, n, p)?;
        b.bend(self.lookup(b.map, b.uv), front)
    }

    /// What [`mapped_normal`](Self::mapped_normal) reads the normal
    /// texture with, before the lookup: the material's map, the texture
    /// coordinates at `p`, and the tangent frame about the shading normal
    /// `n`. `None` where there is nothing to bend (no texture, no
    /// tangents, a degenerate tangent).
    #[inline(always)]
    fn normal_frame(&self, prim: usize, n: V3<f32>, p: V3<f32>) -> Option<NormalFrame<'_>> {
        let m = &self.materials[*self.material_of.get(prim)? as usize];
        let map = m.maps.normal.as_ref()?;
        let tangents = self.tangents.get(prim)?;
        let (v, _) = self.uv.get(prim)?;
        let p = glam::Vec3::from(p);
        let b = barycentric(*v, p);
        let t = (0..3).fold(glam::Vec3::ZERO, |s, k| {
            s + glam::Vec3::new(tangents[k][0], tangents[k][1], tangents[k][2]) * b[k]
        });
        let n = glam::Vec3::from(n);
        let t = (t - n * n.dot(t)).normalize_or_zero();
        if t == glam::Vec3::ZERO {
            return None;
        }
        let w = if tangents[0][3] < 0.0 { -1.0 } else { 1.0 };
        let bitangent = n.cross(t) * w;
        let uv = self.texcoords(prim, V3::from(p));
        Some(NormalFrame {
            map,
            uv,
            t,
            bitangent,
            n,
        })
    }

    /// A smooth triangle's front shading normal from its vertex normals
    /// ([`shading_normal`](Self::shading_normal) without normal textures).
    #[inline(always)]
    fn vertex_normal(&self, prim: usize, front: V3<f32>, p: V3<f32>) -> Option<V3<f32>> {
        let (v, n) = self.smooth.get(prim)?;
        if *n == [glam::Vec3::ZERO; 3] {
            return None;
        }
        let front = glam::Vec3::from(front);
        Some(V3::from(interpolate_normal(
            *v,
            *n,
            front,
            glam::Vec3::from(p),
        )))
    }

    /// The model of the material of primitive `tri`.
    #[inline(always)]
    pub fn model_of(&self, tri: u32) -> Model {
        self.model[self.material_of[tri as usize] as usize]
    }

    /// The surfaces of eight triangles (any row: lanes past the live paths
    /// repeat one), all of model `model`, from their materials' constant
    /// parameters ([`Constants::gather`]; a model whose parameters are the
    /// diffuse BRDF reads it from the primitives' rows).
    #[inline(always)]
    pub fn surfaces(&self, model: Model, tris: &[usize; 8]) -> Surface<f32x8> {
        let mats = || tris.map(|t| self.material_of[t] as usize);
        self.constants.gather(model, mats, || {
            let [_, _, _, r, g, b, ..] = self.rows_8(tris);
            V3::new(r, g, b)
        })
    }

    /// Whether some material absorbs light inside it
    /// ([`Material::absorbs`]).
    #[inline(always)]
    pub fn has_absorption(&self) -> bool {
        self.absorbing
    }

    /// Whether the material of primitive `prim` absorbs light inside it
    /// ([`Material::absorbs`]): the cheap test before
    /// [`transmittance`](Self::transmittance) needs the hit's surface.
    #[inline]
    pub fn absorbs(&self, prim: u32) -> bool {
        self.absorbing
            && (self.material_of.get(prim as usize))
                .is_some_and(|&m| self.materials[m as usize].absorbs())
    }

    /// What reaches the hit `hit` of a ray from inside the medium it
    /// travelled through: where the hit is on the back of a material that
    /// absorbs ([`Material::absorbs`]: the ray crossed its solid from the
    /// point it entered, or left, to here), the transmittance of the
    /// segment's length `t` ([`Material::transmittance`]); `None`
    /// elsewhere. The one factor both engines multiply the path's
    /// throughput by, before anything else at the vertex.
    #[inline]
    pub fn transmittance(&self, hit: &SurfaceHit<f32>, t: f32) -> Option<[f32; 3]> {
        if !self.absorbing || hit.front {
            return None;
        }
        self.materials[hit.material as usize].transmittance(t)
    }

    /// Whether some material's emission is textured: emitted radiance is
    /// then [`emission_at`](Self::emission_at) the point, not the
    /// material's constant [`emission`](Self::emission).
    #[inline(always)]
    pub fn has_emissive_maps(&self) -> bool {
        self.emissive_maps
    }

    /// The radiance material `material` emits (towards its front) at a
    /// point of texture coordinates `uv`: where its emission is textured,
    /// its [`emissive_factor`](crate::scene::material::Maps::emissive_factor)
    /// × the texture's RGB there (sRGB-decoded at load, after
    /// `KHR_texture_transform`); else its constant
    /// [`emission`](Self::emission), bit for bit. The one lookup both
    /// engines make, for a hit a ray finds and for a point light sampling
    /// picks ([`light_emission`](Self::light_emission)), so both weigh
    /// the same radiance.
    #[inline]
    pub fn emission_at(&self, material: u32, uv: [[f32; 2]; 2]) -> [f32; 3] {
        let m = &self.materials[material as usize];
        match &m.maps.emissive {
            Some(t) => {
                let at = t.transform.apply(uv[(t.tex_coord as usize).min(1)]);
                let c = self.textures[t.texture as usize].sample(t.sampler, at[0], at[1]);
                let f = m.maps.emissive_factor;
                [f.x * c[0], f.y * c[1], f.z * c[2]]
            }
            None => self.emission[material as usize],
        }
    }

    /// The radiance emitted at the point `p` of primitive `prim` (a
    /// point light sampling picked on an emitter): [`emission_at`](Self::emission_at)
    /// its texture coordinates ([`texcoords`](Self::texcoords), as a hit
    /// there has them). `None` where `prim` is no primitive (a point of
    /// the environment) or its emission is not textured.
    #[inline]
    pub fn light_emission(&self, prim: u32, p: V3<f32>) -> Option<[f32; 3]> {
        let material = *self.material_of.get(prim as usize)?;
        self.materials[material as usize].maps.emissive.as_ref()?;
        Some(self.emission_at(material, self.texcoords(prim as usize, p)))
    }

    /// [`light_emission`](Self::light_emission) of eight lanes (the
    /// first `lanes`; `None` in the others): the primitives `prims` at
    /// the points `p`, their emission textures read for the lanes at once
    /// (`lookup_8`: [`sample_lanes`] per texture), the same bits; on the texture
    /// clock ([`timed`](crate::integrator::texture::timed)) where some
    /// lane reads one.
    #[inline]
    pub fn light_emissions_8(
        &self,
        prims: [u32; 8],
        p: [V3<f32>; 8],
        lanes: usize,
    ) -> [Option<[f32; 3]>; 8] {
        let materials: [Option<&Material>; 8] = std::array::from_fn(|l| {
            let m = self
                .material_of
                .get(prims[l] as usize)
                .filter(|_| l < lanes)?;
            Some(&self.materials[*m as usize])
        });
        let maps = materials.map(|m| m.and_then(|m| m.maps.emissive.as_ref()));
        if maps.iter().all(Option::is_none) {
            return [None; 8];
        }
        crate::integrator::texture::timed(|| {
            let uv: [_; 8] = std::array::from_fn(|l| match maps[l] {
                Some(_) => self.texcoords(prims[l] as usize, p[l]),
                None => [[0.0; 2]; 2],
            });
            let c = self.lookup_8(&maps, &uv);
            std::array::from_fn(|l| {
                maps[l]?;
                let f = materials[l]?.maps.emissive_factor;
                Some([f.x * c[l][0], f.y * c[l][1], f.z * c[l][2]])
            })
        })
    }

    /// Whether some surface may let rays through ([`Tables::passes`]).
    #[inline(always)]
    pub fn has_cutouts(&self) -> bool {
        self.cutouts
    }

    /// The any-hit filter of the ray `(o, d)` for the hierarchy's filtered
    /// queries ([`Bvh::closest_hit_filtered`](crate::accel::bvh::Bvh::closest_hit_filtered)):
    /// hits on primitives of materials that are not opaque are put to
    /// [`Tables::passes`]; the rest are kept untested.
    #[inline(always)]
    pub fn cutouts(&self, (o, d): (V3<f32>, V3<f32>)) -> Cutouts<'_> {
        Cutouts {
            tables: self,
            ray: (o, d),
        }
    }

    /// [`Tables::cutouts`] of ray `i` of rays given as columns.
    #[inline(always)]
    pub fn cutouts_of(&self, (o, d): ([&[f32]; 3], [&[f32]; 3]), i: usize) -> Cutouts<'_> {
        self.cutouts((
            V3::new(o[0][i], o[1][i], o[2][i]),
            V3::new(d[0][i], d[1][i], d[2][i]),
        ))
    }

    /// Whether the ray `(o, d)` passes through primitive `prim`, which it
    /// hits at distance `t`: where its material's [`Coverage`] leaves the
    /// surface out there (alpha: the material's opacity × its base colour
    /// texture's alpha × the triangle's vertex colour alpha, at the hit).
    /// `Blend` lets the ray through with probability `1 − alpha`, by a
    /// number hashed from the bits of `o`, `d` and `prim` (a function of
    /// the path's numbers, as the engines trace the same rays bit for
    /// bit). The one test both engines make, for camera, scattered and
    /// shadow rays.
    pub fn passes(&self, prim: usize, (o, d): (V3<f32>, V3<f32>), t: f32) -> bool {
        let m = &self.materials[self.material_of[prim] as usize];
        if m.coverage == Coverage::Opaque {
            return false;
        }
        let p = hit_point(o, d, t);
        let uv = self.texcoords(prim, p);
        let mut alpha = m.opacity;
        if let Some(t) = &m.maps.base_colour {
            let at = t.transform.apply(uv[(t.tex_coord as usize).min(1)]);
            alpha *= self.textures[t.texture as usize].sample(t.sampler, at[0], at[1])[3];
        }
        if let Some((v, c)) = self.colours.get(prim) {
            let b = barycentric(*v, glam::Vec3::from(p));
            alpha *= c[0][3] * b[0] + c[1][3] * b[1] + c[2][3] * b[2];
        }
        match m.coverage {
            Coverage::Opaque => false,
            Coverage::Mask(cutoff) => alpha < cutoff,
            Coverage::Blend => {
                // The bytes hashed in one call (XXH3 of a whole input is
                // the streaming hasher's digest of it, bit for bit).
                let mut bytes = [0u8; 36];
                for (k, x) in [o.x, o.y, o.z, d.x, d.y, d.z, t].iter().enumerate() {
                    bytes[4 * k..4 * k + 4].copy_from_slice(&x.to_bits().to_le_bytes());
                }
                bytes[28..].copy_from_slice(&(prim as u64).to_le_bytes());
                let h = xxhash_rust::xxh3::xxh3_64(&bytes);
                let u = (h >> 40) as f32 / (1u32 << 24) as f32;
                u >= alpha
            }
        }
    }

    /// Whether surfaces of `model` have parameters looked up per hit
    /// (textures or vertex colours).
    #[inline(always)]
    pub fn is_textured(&self, model: Model) -> bool {
        self.textured[model as usize]
    }

    /// The scattering of the surface at `hit` (one lane): its material's
    /// ([`Surface::of`]), or, where the material is textured or the
    /// triangle has vertex colours, with those looked up at the hit
    /// ([`Surface::at`] its texels). The one lookup both engines make, so
    /// they scatter with the same bits.
    #[inline]
    pub fn scattering(&self, hit: &SurfaceHit<f32>) -> Surface<f32> {
        self.scattering_at(hit.prim as usize, hit.material, hit.uv, hit.p)
    }

    /// Texture `t` at the texture coordinates `uv` (sets 0 and 1).
    #[inline]
    fn lookup(&self, t: &TextureRef, uv: [[f32; 2]; 2]) -> [f32; 4] {
        let at = t.transform.apply(uv[(t.tex_coord as usize).min(1)]);
        self.textures[t.texture as usize].sample(t.sampler, at[0], at[1])
    }

    /// [`lookup`](Self::lookup) of eight lanes: lane `l`'s texture
    /// `maps[l]` at its texture coordinates `uv[l]` (zero where
    /// `maps[l]` is `None`), the same bits. The lanes that read one
    /// texture with one sampler are looked up together, in one
    /// [`sample_lanes`] (each at its coordinates through its own map's set
    /// and transform; the other lanes at 0, their results dropped): one
    /// call where the eight lanes read the same texture, at most eight.
    #[inline(always)]
    fn lookup_8(&self, maps: &[Option<&TextureRef>; 8], uv: &[[[f32; 2]; 2]; 8]) -> [[f32; 4]; 8] {
        let mut out = [[0.0; 4]; 8];
        let mut todo = (0..8).fold(0u8, |m, l| m | (u8::from(maps[l].is_some()) << l));
        while todo != 0 {
            let Some(first) = maps[todo.trailing_zeros() as usize] else {
                unreachable!("a lane to look up has a map")
            };
            let (texture, sampler) = (first.texture, first.sampler);
            let (mut u, mut v) = ([0.0f32; 8], [0.0f32; 8]);
            let mut group = 0u8;
            for l in 0..8 {
                if let Some(t) = maps[l]
                    && todo & (1 << l) != 0
                    && t.texture == texture
                    && t.sampler == sampler
                {
                    [u[l], v[l]] = t.transform.apply(uv[l][(t.tex_coord as usize).min(1)]);
                    group |= 1 << l;
                }
            }
            todo &= !group;
            let texture = &self.textures[texture as usize];
            let c = sample_lanes(texture, sampler, f32x8::from(u), f32x8::from(v));
            let c = [
                c[0].to_array(),
                c[1].to_array(),
                c[2].to_array(),
                c[3].to_array(),
            ];
            for (l, out) in out.iter_mut().enumerate() {
                if group & (1 << l) != 0 {
                    *out = [c[0][l], c[1][l], c[2][l], c[3][l]];
                }
            }
        }
        out
    }

    /// What multiplies material `m`'s colour on primitive `prim` at the
    /// point `p` of texture coordinates `uv`: its base colour texture
    /// there times the triangle's vertex colours (1 without either).
    #[inline]
    fn colour_at(&self, prim: usize, m: &Material, uv: [[f32; 2]; 2], p: V3<f32>) -> glam::Vec3 {
        let base = (m.maps.base_colour.as_ref()).map(|t| self.lookup(t, uv));
        self.tint(prim, base, p)
    }

    /// [`colour_at`](Self::colour_at) from the base colour texture's
    /// texel `base` there (`None`: the material has none).
    #[inline(always)]
    fn tint(&self, prim: usize, base: Option<[f32; 4]>, p: V3<f32>) -> glam::Vec3 {
        let mut colour = glam::Vec3::ONE;
        if let Some(c) = base {
            colour = glam::Vec3::new(c[0], c[1], c[2]);
        }
        if let Some((v, c)) = self.colours.get(prim) {
            let b = barycentric(*v, glam::Vec3::from(p));
            let at = |k: usize| c[0][k] * b[0] + c[1][k] * b[1] + c[2][k] * b[2];
            colour *= glam::Vec3::new(at(0), at(1), at(2));
        }
        colour
    }

    /// The albedo AOV at `hit`: its
    /// material's reflectance times the base colour texture and vertex
    /// colours there, clamped to [0, 1] (the material's
    /// [`albedo`](Self::albedo) where nothing is looked up per hit).
    pub fn albedo_at(&self, hit: &SurfaceHit<f32>) -> [f32; 3] {
        let m = &self.materials[hit.material as usize];
        if !self.is_textured(m.model) {
            return self.albedo[hit.material as usize];
        }
        let colour = self.colour_at(hit.prim as usize, m, hit.uv, hit.p);
        (m.reflectance * colour)
            .clamp(glam::Vec3::ZERO, glam::Vec3::ONE)
            .to_array()
    }

    /// [`scattering`](Self::scattering) of primitive `prim` of material
    /// `material` at the point `p` of texture coordinates `uv`.
    #[inline]
    fn scattering_at(
        &self,
        prim: usize,
        material: u32,
        uv: [[f32; 2]; 2],
        p: V3<f32>,
    ) -> Surface<f32> {
        let m = &self.materials[material as usize];
        if !self.is_textured(m.model) {
            return Surface::of(m);
        }
        let colour = self.colour_at(prim, m, uv, p);
        Surface::at(
            m,
            &AtHit {
                tables: self,
                uv,
                colour,
            },
        )
    }

    /// [`surfaces`](Self::surfaces) of eight lanes at their hits `hit`:
    /// for a textured model, each lane's [`scattering`](Self::scattering)
    /// (the reference tracer's bits); else the constant columns.
    #[inline(always)]
    pub fn surfaces_at(
        &self,
        model: Model,
        tris: &[usize; 8],
        hit: &SurfaceHit<f32x8>,
    ) -> Surface<f32x8> {
        if !self.is_textured(model) {
            return self.surfaces(model, tris);
        }
        let p = lanes3(hit.p);
        let uv = hit.uv.map(|set| set.map(|c| c.to_array()));
        let uv: [[[f32; 2]; 2]; 8] = std::array::from_fn(|l| uv.map(|set| set.map(|c| c[l])));
        crate::integrator::texture::timed(|| {
            // Each lane's `scattering_at`, its maps read for the eight
            // lanes at once, map by map (`lookup_8`): the same bits.
            let materials: [&Material; 8] =
                std::array::from_fn(|l| &self.materials[hit.material[l] as usize]);
            let maps = materials.map(scattering_maps);
            let used = self.maps_of_model[model as usize];
            let mut texels = [[[0.0; 4]; 8]; SCATTERING_MAPS];
            for (k, texels) in texels.iter_mut().enumerate() {
                if used & (1 << k) != 0 {
                    *texels = self.lookup_8(&maps.map(|m| m[k]), &uv);
                }
            }
            Surface::lanes(model, |l| {
                let base = maps[l][0].map(|_| texels[0][l]);
                let looked = Looked {
                    tables: self,
                    uv: uv[l],
                    colour: self.tint(tris[l], base, p[l]),
                    maps: &maps[l],
                    texels: &texels,
                    lane: l,
                };
                Surface::at(materials[l], &looked)
            })
        })
    }

    /// The one model every material has, if they all have the same.
    pub fn single_model(&self) -> Option<Model> {
        let first = *self.model.first()?;
        self.model.iter().all(|m| *m == first).then_some(first)
    }
}

/// What a material's textures read at a hit ([`Tables::scattering`]):
/// its texture coordinates there, and its colour (base colour texture ×
/// vertex colours).
struct AtHit<'a> {
    tables: &'a Tables,
    uv: [[f32; 2]; 2],
    colour: glam::Vec3,
}

impl Texels for AtHit<'_> {
    #[inline]
    fn colour(&self) -> glam::Vec3 {
        self.colour
    }
    #[inline]
    fn read(&self, map: Option<&TextureRef>) -> Option<[f32; 4]> {
        map.map(|t| self.tables.lookup(t, self.uv))
    }
}

/// How many of a material's maps its scattering parameters read
/// ([`scattering_maps`]).
const SCATTERING_MAPS: usize = 5;

/// The maps of material `m` its scattering parameters read
/// ([`Surface::at`]), base colour first.
#[inline(always)]
fn scattering_maps(m: &Material) -> [Option<&TextureRef>; SCATTERING_MAPS] {
    let maps = &m.maps;
    [
        maps.base_colour.as_ref(),
        maps.metallic_roughness.as_ref(),
        maps.transmission.as_ref(),
        maps.specular.as_ref(),
        maps.specular_colour.as_ref(),
    ]
}

/// What a material's textures read at a hit, looked up already (for a
/// lane of [`Tables::surfaces_at`]): its colour, and the texels of its
/// [`scattering_maps`] there. A map that is none of those (no model asks
/// for one) is looked up as [`AtHit`] does it.
struct Looked<'a> {
    tables: &'a Tables,
    uv: [[f32; 2]; 2],
    colour: glam::Vec3,
    /// The lane's material's maps.
    maps: &'a [Option<&'a TextureRef>; SCATTERING_MAPS],
    /// Per map, each lane's texel.
    texels: &'a [[[f32; 4]; 8]; SCATTERING_MAPS],
    lane: usize,
}

impl Texels for Looked<'_> {
    #[inline(always)]
    fn colour(&self) -> glam::Vec3 {
        self.colour
    }
    #[inline(always)]
    fn read(&self, map: Option<&TextureRef>) -> Option<[f32; 4]> {
        let map = map?;
        for (k, m) in self.maps.iter().enumerate() {
            if m.is_some_and(|m| std::ptr::eq(m, map)) {
                return Some(self.texels[k][self.lane]);
            }
        }
        Some(self.tables.lookup(map, self.uv))
    }
}

/// What a normal texture bends at a hit ([`Tables::normal_frame`]): the
/// map, the texture coordinates there, and the frame (the tangent `t`,
/// the bitangent and the shading normal `n` it bends).
struct NormalFrame<'a> {
    map: &'a TextureRef,
    uv: [[f32; 2]; 2],
    t: glam::Vec3,
    bitangent: glam::Vec3,
    n: glam::Vec3,
}

impl NormalFrame<'_> {
    /// The normal the texel `c` (the map at the hit) makes of the frame,
    /// as [`Tables::mapped_normal`] defines it: `None` where it is
    /// degenerate or turns below the geometric front normal `front`.
    #[inline(always)]
    fn bend(&self, c: [f32; 4], front: V3<f32>) -> Option<V3<f32>> {
        let scale = self.map.scale;
        let (x, y, z) = (
            (2.0 * c[0] - 1.0) * scale,
            (2.0 * c[1] - 1.0) * scale,
            2.0 * c[2] - 1.0,
        );
        let bent = (self.t * x + self.bitangent * y + self.n * z).normalize_or_zero();
        let above = bent.dot(glam::Vec3::from(front)) > 0.0;
        (above && bent.is_finite()).then(|| V3::from(bent))
    }
}

/// Each kind's [`Shape::Surface`] data, per primitive of the kind.
struct SurfacesOf;

impl Family for SurfacesOf {
    type Of<S: Shape> = Vec<S::Surface>;
}

/// What [`Tables::new`] takes from each kind.
struct KindTables {
    /// Each primitive's material, kind after kind.
    materials: Vec<u32>,
    /// Each primitive's flat front normal (zero where it has none).
    flat_normals: Vec<glam::Vec3>,
    firsts: [usize; Shapes::COUNT],
    surfaces: Kinds<SurfacesOf>,
    curved: bool,
}

impl KindTables {
    fn of(scene: &Scene) -> Self {
        struct Gather<'a> {
            scene: &'a Scene,
            materials: Vec<u32>,
            flat_normals: Vec<glam::Vec3>,
            counts: [usize; Shapes::COUNT],
            curved: bool,
        }
        impl Make<SurfacesOf> for Gather<'_> {
            fn make<S: Shape>(&mut self) -> Vec<S::Surface> {
                let surfaces = S::surfaces(self.scene);
                self.counts[S::KIND as usize] = surfaces.len();
                self.materials.extend(S::materials(self.scene));
                for s in &surfaces {
                    let flat = S::flat_normal(s);
                    self.curved |= flat.is_none();
                    self.flat_normals.push(flat.unwrap_or(glam::Vec3::ZERO));
                }
                surfaces
            }
        }
        let mut g = Gather {
            scene,
            materials: Vec::new(),
            flat_normals: Vec::new(),
            counts: [0; Shapes::COUNT],
            curved: false,
        };
        let surfaces = Kinds::new(&mut g);
        let counts = g.counts;
        let mut firsts = [0; Shapes::COUNT];
        for (k, f) in firsts.iter_mut().enumerate() {
            *f = counts[..k].iter().sum();
        }
        Self {
            materials: g.materials,
            flat_normals: g.flat_normals,
            firsts,
            surfaces,
            curved: g.curved,
        }
    }
}

/// [`Shape::front_normal`] of a kind's primitive `i` at the hit `t` of the
/// ray `o + t·d`.
struct FrontNormal {
    i: usize,
    o: V3<f32>,
    d: V3<f32>,
    t: f32,
}

impl VisitOne<SurfacesOf> for FrontNormal {
    type Out = V3<f32>;
    #[inline(always)]
    fn visit<S: Shape>(self, surfaces: &Vec<S::Surface>) -> V3<f32> {
        S::front_normal(&surfaces[self.i], self.o, self.d, self.t)
    }
}

/// [`FrontNormal`] where the kind's normal is not flat, else `None`.
struct CurvedNormal(FrontNormal);

impl VisitOne<SurfacesOf> for CurvedNormal {
    type Out = Option<V3<f32>>;
    #[inline(always)]
    fn visit<S: Shape>(self, surfaces: &Vec<S::Surface>) -> Option<V3<f32>> {
        let s = &surfaces[self.0.i];
        S::flat_normal(s)
            .is_none()
            .then(|| S::front_normal(s, self.0.o, self.0.d, self.0.t))
    }
}

/// Eight 3-vectors as eight scalar ones.
#[inline(always)]
fn lanes3(v: Vec3x8) -> [V3<f32>; 8] {
    let (x, y, z) = (v.x.to_array(), v.y.to_array(), v.z.to_array());
    std::array::from_fn(|l| V3::new(x[l], y[l], z[l]))
}

/// `v` with lane `l` replaced by `new(l)` where that is `Some`.
#[inline(always)]
fn replace_lanes(v: Vec3x8, mut new: impl FnMut(usize) -> Option<V3<f32>>) -> Vec3x8 {
    let (mut x, mut y, mut z) = (v.x.to_array(), v.y.to_array(), v.z.to_array());
    for (l, ((x, y), z)) in x.iter_mut().zip(&mut y).zip(&mut z).enumerate() {
        if let Some(n) = new(l) {
            (*x, *y, *z) = (n.x, n.y, n.z);
        }
    }
    V3::new(f32x8::from(x), f32x8::from(y), f32x8::from(z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::triangle::NO_PRIM;
    use crate::integrator::sampler::PathRng;

    /// Eight lanes' surfaces are each lane's own, bit for bit, in a scene
    /// of flat and smooth triangles and spheres, wherever the rays come
    /// from; and a flat scene's shading normal is its facing normal.
    #[test]
    fn eight_lanes_make_each_lanes_surface() {
        let mut scene = Scene::cornell();
        let material = scene.triangles[0].material;
        let center = glam::Vec3::new(0.2, 0.1, 0.3);
        scene.spheres.push(crate::scene::Sphere {
            center,
            radius: 0.3,
            material,
        });
        let flat = Tables::new(&scene);
        let mut rng = PathRng::new(1, 2, 3);
        let mut u = || rng.next_f32() - 0.5;
        // Every other triangle smooth, with tilted vertex normals.
        scene.vertex_normals = (scene.triangles.iter().enumerate())
            .map(|(i, t)| match i % 2 {
                0 => [glam::Vec3::ZERO; 3],
                _ => [0.3, -0.2, 0.1].map(|k| (t.normal + glam::Vec3::splat(k)).normalize()),
            })
            .collect();
        let smooth = Tables::new(&scene);
        // Texture coordinates on every triangle but the first.
        scene.texturing.uv = (0..scene.triangles.len())
            .map(|i| match i {
                0 => [[[0.0; 2]; 3]; 2],
                _ => std::array::from_fn(|_| std::array::from_fn(|_| [u(), u()])),
            })
            .collect();
        let textured = Tables::new(&scene);
        let prims = scene.triangles.len() + 1;
        for tables in [&flat, &smooth, &textured] {
            for round in 0..200 {
                let ps: [usize; 8] = std::array::from_fn(|l| (round * 8 + l * 5) % prims);
                let v = |u: &mut dyn FnMut() -> f32| V3::new(u(), u(), u());
                type Ray = (V3<f32>, V3<f32>, f32);
                let rays: [Ray; 8] = std::array::from_fn(|_| (v(&mut u), v(&mut u), u() + 0.5));
                let col = |f: fn(&Ray) -> f32| f32x8::from(rays.map(|r| f(&r)));
                let o = V3::new(col(|r| r.0.x), col(|r| r.0.y), col(|r| r.0.z));
                let d = V3::new(col(|r| r.1.x), col(|r| r.1.y), col(|r| r.1.z));
                let all = tables.surface_8(&ps, (o, d), col(|r| r.2));
                let bits = |v: V3<f32>| [v.x, v.y, v.z].map(f32::to_bits);
                let lane = |v: Vec3x8, l: usize| bits(lanes3(v)[l]);
                for (l, &(o, d, t)) in rays.iter().enumerate() {
                    let one = tables.surface(ps[l], (o, d), t);
                    let front = all.front.to_array()[l] != 0.0;
                    assert_eq!(
                        (one.front, one.prim, one.material),
                        (front, all.prim[l], all.material[l])
                    );
                    let uv = all.uv.map(|set| set.map(|c| c.to_array()[l].to_bits()));
                    assert_eq!(one.uv.map(|set| set.map(f32::to_bits)), uv, "lane {l}");
                    if !tables.has_uv() {
                        assert_eq!(one.uv, [[0.0; 2]; 2]);
                    }
                    for (a, b) in [
                        (one.p, all.p),
                        (one.ng, all.ng),
                        (one.n, all.n),
                        (one.ns, all.ns),
                    ] {
                        assert_eq!(bits(a), lane(b, l), "lane {l} of primitive {}", ps[l]);
                    }
                    if !tables.has_smooth() || ps[l].is_multiple_of(2) {
                        assert_eq!(bits(one.ns), bits(one.n));
                    }
                }
            }
        }
    }

    /// A scene of the Cornell box's triangles, each of one of three
    /// materials per model: one reading every map (base colour,
    /// metallic-roughness, transmission, specular, specular colour,
    /// normal, emission: textures of several sizes, both colour spaces,
    /// every wrap and filter, transforms, both coordinate sets, some maps
    /// sharing a texture with another sampler or transform), one reading
    /// other textures and some of the same ones otherwise, and one reading
    /// none; random texture coordinates, tangents and vertex colours.
    fn textured_scene() -> Scene {
        use crate::scene::texture::{ColourSpace, Filter, Sampler, UvTransform, Wrap};
        let mut scene = Scene::cornell();
        let mut rng = PathRng::new(7, 8, 9);
        let mut u = move || rng.next_f32();
        let mut texture = |w: usize, h: usize, space| {
            let texels = (0..w * h)
                .map(|_| [0; 4].map(|_: u8| (u() * 256.0) as u8))
                .collect();
            Texture::from_rgba8(w, h, texels, space).unwrap()
        };
        let textures = vec![
            texture(13, 7, ColourSpace::Srgb),
            texture(16, 16, ColourSpace::Linear),
            texture(5, 9, ColourSpace::Linear),
            texture(7, 5, ColourSpace::Srgb),
            texture(9, 9, ColourSpace::Srgb),
        ];
        let sampler = |wrap_u, wrap_v, filter| Sampler {
            wrap_u,
            wrap_v,
            filter,
        };
        let (repeat, clamp, mirror) = (Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat);
        let map = |texture, tex_coord, sampler, transform| {
            Some(TextureRef {
                texture,
                tex_coord,
                sampler,
                transform,
                scale: 1.0,
            })
        };
        let turned = UvTransform::new([0.3, -0.2], 0.7, [1.5, 0.8]);
        let other = UvTransform::new([-0.1, 0.4], -0.3, [0.9, 2.1]);
        let id = UvTransform::IDENTITY;
        let linear = sampler(repeat, repeat, Filter::Linear);
        let nearest = sampler(mirror, clamp, Filter::Nearest);
        let all = crate::scene::material::Maps {
            base_colour: map(0, 0, linear, turned),
            metallic_roughness: map(1, 1, nearest, id),
            transmission: map(1, 0, nearest, other),
            emissive: map(3, 0, sampler(clamp, mirror, Filter::Linear), turned),
            emissive_factor: glam::Vec3::new(2.0, 0.5, 1.25),
            specular: map(4, 0, sampler(clamp, repeat, Filter::Linear), id),
            specular_colour: map(0, 1, nearest, id),
            normal: map(2, 0, sampler(repeat, mirror, Filter::Linear), other).map(|mut t| {
                t.scale = 0.7;
                t
            }),
        };
        let some = crate::scene::material::Maps {
            base_colour: map(4, 1, sampler(clamp, clamp, Filter::Linear), other),
            metallic_roughness: map(1, 0, linear, turned),
            normal: map(2, 1, linear, id),
            emissive: map(3, 1, nearest, id),
            emissive_factor: glam::Vec3::ONE,
            ..Default::default()
        };
        let mut materials = Vec::new();
        for model in Model::ALL {
            for maps in [&all, &some, &Default::default()] {
                let mut m =
                    Material::diffuse("m", glam::Vec3::new(0.7, 0.5, 0.3), glam::Vec3::ZERO);
                m.model = model;
                (m.metallic, m.roughness, m.transmission) = (0.6, 0.4, 0.5);
                m.maps = maps.clone();
                if m.maps.emissive.is_some() {
                    m.emission = glam::Vec3::splat(0.5);
                }
                materials.push(m);
            }
        }
        for (i, t) in scene.triangles.iter_mut().enumerate() {
            t.material = (i % materials.len()) as u32;
        }
        scene.materials = materials;
        let n = scene.triangles.len();
        let mut u = {
            let mut rng = PathRng::new(1, 1, 1);
            move || rng.next_f32()
        };
        scene.texturing.uv = (0..n)
            .map(|_| [0; 2].map(|_| [0; 3].map(|_| [u() * 5.0 - 2.0, u() * 5.0 - 2.0])))
            .collect();
        scene.texturing.colours = (0..n)
            .map(|_| [0; 3].map(|_| [u(), u(), u(), u()]))
            .collect();
        scene.texturing.tangents = (0..n)
            .map(|_| {
                let w = if u() < 0.5 { -1.0 } else { 1.0 };
                [0; 3].map(|_| [u() - 0.5, u() - 0.5, u() - 0.5, w])
            })
            .collect();
        scene.texturing.textures = Arc::new(textures);
        scene
    }

    /// The engine's eight-lane surfaces of textured materials (their maps
    /// read for the lanes at once) are each lane's `scattering` (the
    /// reference tracer's scalar lookups), bit for bit, for lanes of one
    /// material and of mixed ones (some untextured, some reading other
    /// textures, or the same ones with another sampler or transform); so
    /// are the normal-mapped shading normals and the textured emission
    /// light sampling reads.
    #[test]
    fn eight_lanes_read_textures_as_each_lane_does() {
        let scene = textured_scene();
        let tables = Tables::new(&scene);
        assert!(tables.normal_maps && tables.has_emissive_maps());
        let mut rng = PathRng::new(3, 1, 4);
        let mut u = || rng.next_f32();
        let (mut bent, mut emitting) = (0, 0);
        for model in Model::ALL {
            assert!(tables.is_textured(model));
            let tris: Vec<usize> = (0..scene.triangles.len())
                .filter(|&i| tables.model_of(i as u32) == model)
                .collect();
            for round in 0..300 {
                // All lanes on one triangle, on one material, or mixed.
                let pick = |u: &mut dyn FnMut() -> f32| tris[(u() * tris.len() as f32) as usize];
                let first = pick(&mut u);
                let same: Vec<usize> = (tris.iter().copied())
                    .filter(|&t| tables.material_of[t] == tables.material_of[first])
                    .collect();
                let ps: [usize; 8] = std::array::from_fn(|_| match round % 3 {
                    0 => first,
                    1 => same[(u() * same.len() as f32) as usize],
                    _ => pick(&mut u),
                });
                let v = |u: &mut dyn FnMut() -> f32| V3::new(u() - 0.5, u() - 0.5, u() - 0.5);
                type Ray = (V3<f32>, V3<f32>, f32);
                let rays: [Ray; 8] = std::array::from_fn(|_| (v(&mut u), v(&mut u), u() + 0.5));
                let col = |f: fn(&Ray) -> f32| f32x8::from(rays.map(|r| f(&r)));
                let o = V3::new(col(|r| r.0.x), col(|r| r.0.y), col(|r| r.0.z));
                let d = V3::new(col(|r| r.1.x), col(|r| r.1.y), col(|r| r.1.z));
                let hit = tables.surface_8(&ps, (o, d), col(|r| r.2));
                let ones: [SurfaceHit<f32>; 8] = std::array::from_fn(|l| {
                    tables.surface(ps[l], (rays[l].0, rays[l].1), rays[l].2)
                });
                let lanes = format!("{:?}", tables.surfaces_at(model, &ps, &hit));
                let each = format!(
                    "{:?}",
                    Surface::lanes(model, |l| tables.scattering(&ones[l]))
                );
                assert_eq!(lanes, each, "{model:?}, primitives {ps:?}");
                let bits = |v: V3<f32>| [v.x, v.y, v.z].map(f32::to_bits);
                let ns = lanes3(hit.ns);
                let live = 1 + round % 8;
                let points = lanes3(hit.p);
                let prims = ps.map(|p| p as u32);
                let emitted = tables.light_emissions_8(prims, points, live);
                for l in 0..8 {
                    assert_eq!(
                        bits(ns[l]),
                        bits(ones[l].ns),
                        "{model:?}, lane {l} of {ps:?}"
                    );
                    bent += usize::from(bits(ones[l].ns) != bits(ones[l].n));
                    let want = (l < live)
                        .then(|| tables.light_emission(prims[l], points[l]))
                        .flatten();
                    let got = emitted[l].map(|e| e.map(f32::to_bits));
                    assert_eq!(got, want.map(|e| e.map(f32::to_bits)), "lane {l} of {ps:?}");
                    emitting += usize::from(want.is_some());
                }
            }
        }
        // The normal textures bent normals, and emission was looked up.
        assert!(
            bent > 1000 && emitting > 1000,
            "{bent} bent, {emitting} emitting"
        );
    }

    /// A hit's texture coordinates are its triangle's vertex coordinates
    /// interpolated at the hit, in both sets (at a vertex, that vertex's
    /// own); triangles without any, and spheres, have zero.
    #[test]
    fn texture_coordinates_are_interpolated_at_the_hit() {
        let mut scene = Scene::cornell();
        scene.spheres.push(crate::scene::Sphere {
            center: glam::Vec3::new(0.2, 0.1, 0.3),
            radius: 0.3,
            material: 0,
        });
        let n = scene.triangles.len();
        let coords = |i: usize| -> [[[f32; 2]; 3]; 2] {
            let k = i as f32;
            [
                [[0.1 * k, 0.2], [0.9, 0.3 + k], [0.4, -0.7 * k]],
                [[1.0, 2.0], [3.0, 4.0], [5.0 - k, 6.0]],
            ]
        };
        scene.texturing.uv = (0..n)
            .map(|i| {
                if i == 3 {
                    [[[0.0; 2]; 3]; 2]
                } else {
                    coords(i)
                }
            })
            .collect();
        let tables = Tables::new(&scene);
        let mut rng = PathRng::new(4, 5, 6);
        for i in 0..n {
            let v = scene.triangles[i].v;
            for round in 0..50 {
                // A point of known barycentric coordinates (the vertices
                // themselves first), hit by a ray along the normal.
                let b = match round {
                    0..3 => std::array::from_fn(|k| if k == round { 1.0 } else { 0.0 }),
                    _ => {
                        let (x, y) = (rng.next_f32(), rng.next_f32());
                        let (x, y) = if x + y > 1.0 {
                            (1.0 - x, 1.0 - y)
                        } else {
                            (x, y)
                        };
                        [1.0 - x - y, x, y]
                    }
                };
                let p = v[0] * b[0] + v[1] * b[1] + v[2] * b[2];
                let normal = scene.triangles[i].normal;
                let o = p + normal;
                let hit = tables.surface(i, (V3::from(o), V3::from(-normal)), 1.0);
                let want = if i == 3 {
                    [[[0.0; 2]; 3]; 2]
                } else {
                    coords(i)
                };
                for (set, corners) in want.iter().enumerate() {
                    for c in [0, 1] {
                        let w: f32 = corners.iter().zip(b).map(|(uv, b)| uv[c] * b).sum();
                        let got = hit.uv[set][c];
                        assert!(
                            (got - w).abs() <= 1e-4 * (1.0 + w.abs()),
                            "triangle {i}, b {b:?}: set {set} coordinate {c} is {got}, not {w}"
                        );
                    }
                }
            }
        }
        let sphere = tables.surface(n, (V3::new(0.2, 0.1, 2.0), V3::new(0.0, 0.0, -1.0)), 1.4);
        assert_eq!(sphere.uv, [[0.0; 2]; 2]);
    }

    /// `emits` agrees with the materials for every primitive, and is false
    /// for misses and past the last primitive, wherever the emitters sit
    /// among the primitives.
    #[test]
    fn emits_is_the_materials_emission_for_every_primitive() {
        let base = Scene::cornell();
        let n = base.triangles.len();
        let light = (base.triangles.iter())
            .map(|t| t.material)
            .find(|&m| base.materials[m as usize].emission != glam::Vec3::ZERO)
            .expect("the Cornell box has a light");
        let dark = base.triangles[0].material;
        // The box as it is; no emitter; emitters first, last, and both
        // ends with dark ones between.
        let layouts: [&[usize]; 5] = [&[], &[0], &[n - 1], &[0, n - 1], &[5, 6, 20]];
        for (k, lit) in layouts.iter().enumerate() {
            let mut scene = base.clone();
            if k > 0 {
                for (i, t) in scene.triangles.iter_mut().enumerate() {
                    t.material = if lit.contains(&i) { light } else { dark };
                }
            }
            let tables = Tables::new(&scene);
            for (i, t) in scene.triangles.iter().enumerate() {
                let want = scene.materials[t.material as usize].emission != glam::Vec3::ZERO;
                assert_eq!(tables.emits(i as u32), want, "layout {k}: primitive {i}");
            }
            for h in [NO_PRIM, n as u32, n as u32 + 7, u32::MAX - 1] {
                assert!(!tables.emits(h), "layout {k}: {h} is no primitive");
            }
        }
    }
}

/// The any-hit filter of one ray ([`Tables::cutouts`]): the cut-outs that
/// let it through, as the hierarchy's walk asks about its candidate hits.
#[derive(Clone, Copy)]
pub struct Cutouts<'a> {
    tables: &'a Tables,
    ray: (V3<f32>, V3<f32>),
}

impl HitFilter for Cutouts<'_> {
    #[inline(always)]
    fn may_pass(&self, prim: u32) -> bool {
        let t = self.tables;
        t.see_through[t.material_of[prim as usize] as usize]
    }
    #[inline]
    fn passes(&self, prim: u32, t: f32) -> bool {
        self.tables.passes(prim as usize, self.ray, t)
    }
}
