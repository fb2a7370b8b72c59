//! The scene as the stages read it: per-triangle and per-material columns,
//! gathered 8 lanes at a time.

use crate::integrator::bsdf::Surface;
use crate::math::V3;
use crate::scene::{Material, Model, Scene, Triangle};
use std::f32::consts::PI;
use wide::f32x8;

/// Shading data, one column per field.
pub struct Tables {
    /// Front-side unit normal of each triangle: x, y, z columns.
    pub normals: [Vec<f32>; 3],
    /// Material index of each triangle.
    pub material_of: Vec<u32>,
    /// Emitted radiance of each material.
    pub emission: Vec<[f32; 3]>,
    /// Scattering model of each material.
    pub model: Vec<Model>,
    /// The diffuse BRDF `reflectance / π` of each triangle's material:
    /// R, G, B columns.
    pub brdf: [Vec<f32>; 3],
    /// Each material's colour as [`Surface::tint`] takes it, per RGB
    /// channel (columns indexed by material).
    pub tint: [Vec<f32>; 3],
    /// Each material's GGX roughness (metal).
    pub alpha: Vec<f32>,
    /// Each material's index of refraction (glass).
    pub ior: Vec<f32>,
    /// Smallest hit distance (see [`Scene::ray_epsilon`]).
    pub epsilon: f32,
}

impl Tables {
    /// The tables of `scene`.
    pub fn new(scene: &Scene) -> Self {
        let brdf = |t: &Triangle| scene.materials[t.material as usize].reflectance / PI;
        let tint = |m: &Material| match m.model {
            Model::Diffuse => m.reflectance / PI,
            Model::Mirror | Model::Metal => m.reflectance,
            Model::Glass => m.transmittance,
        };
        Self {
            normals: [0, 1, 2].map(|c| scene.triangles.iter().map(|t| t.normal[c]).collect()),
            material_of: scene.triangles.iter().map(|t| t.material).collect(),
            emission: scene
                .materials
                .iter()
                .map(|m| m.emission.to_array())
                .collect(),
            model: scene.materials.iter().map(|m| m.model).collect(),
            brdf: [0, 1, 2].map(|c| scene.triangles.iter().map(|t| brdf(t)[c]).collect()),
            tint: [0, 1, 2].map(|c| scene.materials.iter().map(|m| tint(m)[c]).collect()),
            alpha: scene.materials.iter().map(|m| m.alpha).collect(),
            ior: scene.materials.iter().map(|m| m.ior).collect(),
            epsilon: scene.ray_epsilon(),
        }
    }

    /// The model of the material of triangle `tri`.
    #[inline(always)]
    pub fn model_of(&self, tri: u32) -> Model {
        self.model[self.material_of[tri as usize] as usize]
    }

    /// The surfaces of eight triangles (any row: lanes past the live paths
    /// repeat one), all of model `model`: diffuse ones from the
    /// per-triangle BRDF columns, the others through their materials.
    #[inline(always)]
    pub fn surfaces(&self, model: Model, tris: &[usize; 8]) -> Surface<f32x8> {
        let of_tri = |col: &Vec<f32>| f32x8::from(tris.map(|t| col[t]));
        if model == Model::Diffuse {
            let brdf = V3::new(
                of_tri(&self.brdf[0]),
                of_tri(&self.brdf[1]),
                of_tri(&self.brdf[2]),
            );
            return Surface::diffuse(brdf);
        }
        let mats = tris.map(|t| self.material_of[t] as usize);
        let of_mat = |col: &Vec<f32>| f32x8::from(mats.map(|m| col[m]));
        Surface {
            model,
            tint: V3::new(
                of_mat(&self.tint[0]),
                of_mat(&self.tint[1]),
                of_mat(&self.tint[2]),
            ),
            alpha: of_mat(&self.alpha),
            ior: of_mat(&self.ior),
        }
    }

    /// The one model every material has, if they all have the same.
    pub fn single_model(&self) -> Option<Model> {
        let first = *self.model.first()?;
        self.model.iter().all(|m| *m == first).then_some(first)
    }
}
