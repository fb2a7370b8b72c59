//! A check of a scene's lights before it is rendered: a scene with no
//! emitter, or whose emitters all face away from every surface (emission
//! is one-sided), renders black, which is worth saying before the render
//! rather than after.

use super::{Integrator, Scene};

/// What is wrong with a scene's lights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightWarning {
    /// No material of the scene's surfaces emits.
    NoLight,
    /// Every emitter's front side faces away from every other surface: the
    /// light reaches nothing (each of `emitters` triangles or spheres).
    FacesNothing {
        /// How many emitting triangles and spheres there are.
        emitters: usize,
    },
}

impl std::fmt::Display for LightWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoLight => f.write_str(
                "the scene has no light: no surface's material has an emission, and rays that \
                 leave the scene return black, so the image will be black",
            ),
            Self::FacesNothing { emitters } => write!(
                f,
                "no light faces any surface: emission is one-sided, and the front of every \
                 emitting surface ({emitters} triangle(s) or sphere(s)) faces away from the rest \
                 of the scene, so their light reaches nothing; list the light's vertices in the \
                 other order (or set front_face), see scenes/README.md"
            ),
        }
    }
}

/// Delta lights (point and spot lights, suns of diameter 0) that an
/// integrator other than `nee` never reaches: no ray can hit them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnreachedLights {
    /// How many delta lights send light.
    pub count: usize,
    /// The integrator that cannot reach them.
    pub integrator: Integrator,
}

impl std::fmt::Display for UnreachedLights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the scene has {} delta light(s) (point, spot, or sun of angle 0): they are reached by \
             next-event estimation only, so the {} integrator renders without their light; use \
             --integrator nee (docs/lights.md)",
            self.count,
            self.integrator.name()
        )
    }
}

/// Emitters examined before the check gives up (and says nothing): each
/// costs a pass over the scene's vertices, and the first one that faces a
/// surface ends the check.
const MAX_EMITTERS_CHECKED: usize = 64;

impl Scene {
    /// The scene's delta lights that `integrator` never reaches (every
    /// integrator but `nee`), if it has any that send light.
    pub fn unreached_lights(&self, integrator: Integrator) -> Option<UnreachedLights> {
        let count = self
            .lights
            .iter()
            .filter(|l| l.is_delta() && l.emits())
            .count();
        (count > 0 && integrator != Integrator::Nee)
            .then_some(UnreachedLights { count, integrator })
    }

    /// What is wrong with the scene's lights, if anything: no emitter at
    /// all, or none whose front side faces any other surface (some vertex
    /// of another primitive strictly in front of an emitting triangle's
    /// plane; some point of another primitive outside an emitting sphere).
    pub fn light_warning(&self) -> Option<LightWarning> {
        // An environment with light lights every surface it can see.
        if let Some(env) = &self.environment
            && env.strength > 0.0
            && env.texels.iter().flatten().any(|&c| c > 0.0)
        {
            return None;
        }
        // So does a sun, point or spot light.
        if self.lights.iter().any(|l| l.emits()) {
            return None;
        }
        let emits = |m: u32| self.materials[m as usize].is_emissive();
        let all = self.primitive_count();
        let emitters: Vec<usize> = (0..all)
            .filter(|&i| emits(self.primitive_material(i)))
            .collect();
        if emitters.is_empty() {
            return Some(LightWarning::NoLight);
        }
        if emitters.len() > MAX_EMITTERS_CHECKED {
            return None;
        }
        let eps = 1e-6 * self.extent();
        // Some point of another primitive in front of emitter `i`.
        let faces_something = |i: usize| {
            (0..all)
                .filter(|&j| j != i)
                .any(|j| self.primitive_balls(j).any(|b| self.in_front_of(i, b, eps)))
        };
        if emitters.iter().any(|&i| faces_something(i)) {
            None
        } else {
            Some(LightWarning::FacesNothing {
                emitters: emitters.len(),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cornell_box_is_lit() {
        assert_eq!(Scene::cornell().light_warning(), None);
    }

    /// A floor and a square light above it, its corners listed `light`.
    fn floor_and_light(light: &str, emission: &str) -> Scene {
        let text = format!(
            "[camera]\nposition = [0.0, 1.5, -4.0]\nlook_at = [0.0, 0.5, 0.0]\nup = [0.0, 1.0, 0.0]\n\
             vfov_deg = 40.0\nwidth = 32\nheight = 24\n\
             [materials.grey]\nreflectance = [0.7, 0.7, 0.7]\n\
             [materials.lamp]\nreflectance = [0.0, 0.0, 0.0]\nemission = {emission}\n\
             [[quad]]\nmaterial = \"grey\"\n\
             vertices = [[-3.0, 0.0, -3.0], [-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0]]\n\
             [[quad]]\nmaterial = \"lamp\"\nvertices = {light}\n"
        );
        super::super::file::parse(&text, "test.toml").unwrap()
    }

    const DOWN: &str = "[[-0.5, 3.0, -0.5], [0.5, 3.0, -0.5], [0.5, 3.0, 0.5], [-0.5, 3.0, 0.5]]";
    const UP: &str = "[[-0.5, 3.0, 0.5], [0.5, 3.0, 0.5], [0.5, 3.0, -0.5], [-0.5, 3.0, -0.5]]";

    #[test]
    fn a_light_turned_away_faces_nothing() {
        assert_eq!(
            floor_and_light(DOWN, "[30.0, 30.0, 30.0]").light_warning(),
            None
        );
        assert_eq!(
            floor_and_light(UP, "[30.0, 30.0, 30.0]").light_warning(),
            Some(LightWarning::FacesNothing { emitters: 2 })
        );
        // A light that faces a surface only a little in front of it (the
        // Cornell box's, turned to its ceiling 0.004 away) does light it.
        let mut scene = Scene::cornell();
        for t in &mut scene.triangles {
            if scene.materials[t.material as usize].is_emissive() {
                t.normal = -t.normal;
            }
        }
        assert_eq!(scene.light_warning(), None);
    }

    #[test]
    fn an_emitting_sphere_faces_what_is_outside_it() {
        let mut scene = floor_and_light(UP, "[30.0, 30.0, 30.0]");
        let lamp = scene.triangles.last().unwrap().material;
        scene.spheres.push(crate::scene::Sphere {
            center: glam::Vec3::new(0.0, 1.0, 0.0),
            radius: 0.5,
            material: lamp,
        });
        assert_eq!(scene.light_warning(), None);
    }

    #[test]
    fn a_scene_without_emission_has_no_light() {
        let scene = floor_and_light(DOWN, "[0.0, 0.0, 0.0]");
        assert_eq!(scene.light_warning(), Some(LightWarning::NoLight));
    }
}
