//! Generated meshes: big scenes without big files.
//!
//! The scene format's `[[generate]]` entries, the tests and the benchmarks
//! all make their meshes here, so they measure and check the same geometry.
//! Every generator is deterministic and returns triangles whose
//! counter-clockwise side (`(v1 - v0) × (v2 - v0)`) faces out (spheres) or
//! up (+y, terrain).

use glam::{DVec3, Vec3};

/// A geodesic sphere of at least `min_triangles` triangles: an icosahedron
/// whose 20 faces are each cut into `f²` triangles, `f = ceil(sqrt(n / 20))`,
/// projected onto the sphere. So it has exactly [`sphere_triangle_count`]
/// triangles. Points shared by two faces are computed in a fixed order from
/// the icosahedron's vertices, so neighbouring faces share them bit for bit:
/// the mesh is watertight.
pub fn geodesic_sphere(center: Vec3, radius: f32, min_triangles: usize) -> Vec<[Vec3; 3]> {
    let f = sphere_frequency(min_triangles);
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let ico: [DVec3; 12] = [
        DVec3::new(-1.0, t, 0.0),
        DVec3::new(1.0, t, 0.0),
        DVec3::new(-1.0, -t, 0.0),
        DVec3::new(1.0, -t, 0.0),
        DVec3::new(0.0, -1.0, t),
        DVec3::new(0.0, 1.0, t),
        DVec3::new(0.0, -1.0, -t),
        DVec3::new(0.0, 1.0, -t),
        DVec3::new(t, 0.0, -1.0),
        DVec3::new(t, 0.0, 1.0),
        DVec3::new(-t, 0.0, -1.0),
        DVec3::new(-t, 0.0, 1.0),
    ];
    const FACES: [[usize; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let c = center.as_dvec3();
    let r = radius as f64;
    // The point with integer barycentric weights `w` (summing to f) on the
    // face with vertex ids `ids`: summed in increasing vertex-id order, so
    // the same point of a shared edge comes out the same from either face.
    let point = |ids: [usize; 3], w: [usize; 3]| -> Vec3 {
        let mut terms = [(ids[0], w[0]), (ids[1], w[1]), (ids[2], w[2])];
        terms.sort_unstable();
        let mut p = DVec3::ZERO;
        for (id, wt) in terms {
            if wt > 0 {
                p += ico[id] * wt as f64;
            }
        }
        (c + p.normalize() * r).as_vec3()
    };
    let mut tris = Vec::with_capacity(20 * f * f);
    for ids in FACES {
        // Row i (from vertex 0), column j (towards vertex 2).
        let p = |i: usize, j: usize| point(ids, [f - i - j, i, j]);
        for i in 0..f {
            for j in 0..f - i {
                tris.push([p(i, j), p(i + 1, j), p(i, j + 1)]);
                if i + j + 1 < f {
                    tris.push([p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
                }
            }
        }
    }
    tris
}

fn sphere_frequency(min_triangles: usize) -> usize {
    let mut f = ((min_triangles as f64 / 20.0).sqrt().ceil() as usize).max(1);
    while 20 * f * f < min_triangles {
        f += 1;
    }
    f
}

/// The number of triangles [`geodesic_sphere`] makes for `min_triangles`.
pub fn sphere_triangle_count(min_triangles: usize) -> usize {
    let f = sphere_frequency(min_triangles);
    20 * f * f
}

/// A displaced terrain grid of at least `min_triangles` triangles: `m × m`
/// cells of two triangles, `m = ceil(sqrt(n / 2))`, over `size.x × size.y`
/// (in x and z) centred on `center`, with heights in
/// `[-height/2, height/2]` from a sum of sines shaped by `seed`.
pub fn terrain(
    center: Vec3,
    size: [f32; 2],
    height: f32,
    min_triangles: usize,
    seed: u64,
) -> Vec<[Vec3; 3]> {
    let m = terrain_cells(min_triangles);
    // Four octaves of sines with seed-dependent phases and directions.
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let waves: Vec<(f64, f64, f64, f64)> = (0..4)
        .map(|k| {
            let angle = next() * std::f64::consts::TAU;
            let freq = std::f64::consts::TAU * (1.5 * 2f64.powi(k));
            (
                angle.cos() * freq,
                angle.sin() * freq,
                next() * std::f64::consts::TAU,
                0.5f64.powi(k),
            )
        })
        .collect();
    let norm: f64 = waves.iter().map(|w| w.3).sum();
    let h = |u: f64, v: f64| -> f64 {
        waves
            .iter()
            .map(|&(a, b, ph, amp)| amp * (a * u + b * v + ph).sin())
            .sum::<f64>()
            / norm
    };
    let (sx, sz) = (size[0] as f64, size[1] as f64);
    let c = center.as_dvec3();
    let vertex = |i: usize, j: usize| -> Vec3 {
        let (u, v) = (i as f64 / m as f64, j as f64 / m as f64);
        (c + DVec3::new(
            (u - 0.5) * sx,
            0.5 * height as f64 * h(u, v),
            (v - 0.5) * sz,
        ))
        .as_vec3()
    };
    let row: Vec<Vec<Vec3>> = (0..=m)
        .map(|j| (0..=m).map(|i| vertex(i, j)).collect())
        .collect();
    let mut tris = Vec::with_capacity(2 * m * m);
    for j in 0..m {
        for i in 0..m {
            let (a, b) = (row[j][i], row[j][i + 1]);
            let (d, e) = (row[j + 1][i], row[j + 1][i + 1]);
            // +y up: (x, z) counter-clockwise seen from above is x → -z.
            tris.push([a, d, b]);
            tris.push([b, d, e]);
        }
    }
    tris
}

fn terrain_cells(min_triangles: usize) -> usize {
    let mut m = ((min_triangles as f64 / 2.0).sqrt().ceil() as usize).max(1);
    while 2 * m * m < min_triangles {
        m += 1;
    }
    m
}

/// The number of triangles [`terrain`] makes for `min_triangles`.
pub fn terrain_triangle_count(min_triangles: usize) -> usize {
    let m = terrain_cells(min_triangles);
    2 * m * m
}

/// The DH2323 Cornell box's 32 triangles (`scenes/cornell.toml`), for
/// tests and benchmarks that put a mesh inside it.
pub fn cornell_box() -> Vec<[Vec3; 3]> {
    crate::scene::Scene::cornell()
        .triangles
        .iter()
        .map(|t| t.v)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_counts_and_orientation() {
        for n in [1, 20, 21, 1000, 10_000] {
            let s = geodesic_sphere(Vec3::new(1.0, 2.0, 3.0), 2.0, n);
            assert_eq!(s.len(), sphere_triangle_count(n));
            assert!(s.len() >= n);
            for t in &s {
                let nrm = (t[1] - t[0]).cross(t[2] - t[0]);
                let mid = (t[0] + t[1] + t[2]) / 3.0 - Vec3::new(1.0, 2.0, 3.0);
                assert!(nrm.dot(mid) > 0.0, "outward");
                for v in t {
                    let r = (*v - Vec3::new(1.0, 2.0, 3.0)).length();
                    assert!((r - 2.0).abs() < 1e-5);
                }
            }
        }
    }

    #[test]
    fn sphere_is_watertight() {
        // Every edge is shared by exactly two triangles, with equal bits.
        let s = geodesic_sphere(Vec3::ZERO, 1.0, 2000);
        let key = |v: Vec3| v.to_array().map(f32::to_bits);
        let mut edges = std::collections::HashMap::new();
        for t in &s {
            for k in 0..3 {
                let (a, b) = (key(t[k]), key(t[(k + 1) % 3]));
                let e = if a < b { (a, b) } else { (b, a) };
                *edges.entry(e).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&c| c == 2));
    }

    #[test]
    fn terrain_counts_and_faces_up() {
        let t = terrain(Vec3::ZERO, [4.0, 2.0], 0.5, 1001, 7);
        assert_eq!(t.len(), terrain_triangle_count(1001));
        assert!(t.len() >= 1001);
        for tri in &t {
            assert!((tri[1] - tri[0]).cross(tri[2] - tri[0]).y > 0.0);
            for v in tri {
                assert!(v.y.abs() <= 0.25 + 1e-6 && v.x.abs() <= 2.0 && v.z.abs() <= 1.0);
            }
        }
        assert_eq!(t, terrain(Vec3::ZERO, [4.0, 2.0], 0.5, 1001, 7));
    }
}
