//! The scene as the stages read it: per-triangle and per-material columns,
//! gathered 8 lanes at a time.

use crate::scene::{Model, Scene, Triangle};
use std::f32::consts::PI;

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
    /// Smallest hit distance (see [`Scene::ray_epsilon`]).
    pub epsilon: f32,
}

impl Tables {
    /// The tables of `scene`.
    pub fn new(scene: &Scene) -> Self {
        let brdf = |t: &Triangle| scene.materials[t.material as usize].reflectance / PI;
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
            epsilon: scene.ray_epsilon(),
        }
    }

    /// The one model every material has, if they all have the same.
    pub fn single_model(&self) -> Option<Model> {
        let first = *self.model.first()?;
        self.model.iter().all(|m| *m == first).then_some(first)
    }
}
