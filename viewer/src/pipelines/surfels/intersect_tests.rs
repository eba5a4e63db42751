//! The c-surfel ray cast (`intersect` in curved.wgsl) on the GPU against a CPU march along
//! each ray over the surface it stands for: heights -bend phi(rho) along the normal, phi
//! linear between the rings, inside the n-gon; bent as the paper's and less, as a curvature
//! asks. Rays come from every side, grazing ones included.

use super::passes::{CURVED_WGSL, SURFEL_WGSL, SurfelUniforms, UNIFORMS_WGSL};
use crate::gpu::{GpuContext, ProjectionPath};
use crate::pipelines::filters::bind;
use crate::pipelines::projection::{FILTERS_WGSL, OCT16_WGSL, RANGE_SEARCH_WGSL};
use crate::pipelines::shader::ShaderSource;
use crate::pipelines::shader_tests::{kernel_output, run_kernel};
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

/// Each case's surfel and ray through `intersect`, the hit out.
const KERNEL_WGSL: &str = r#"
struct Case {
    // xyz the centre, w the radius.
    p: vec4<f32>,
    // xyz the normal, w the bend.
    n: vec4<f32>,
    // The ray's unit direction from the eye.
    e: vec4<f32>,
}
@group(2) @binding(0) var<storage, read> cases: array<Case>;
@group(2) @binding(1) var<storage, read_write> hits: array<vec2<f32>>;

@compute @workgroup_size(64)
fn cast_rays(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&cases) {
        return;
    }
    let c = cases[id.x];
    var s: Surfel;
    s.p = c.p.xyz;
    s.radius = c.p.w;
    s.n = c.n.xyz;
    s.curved = true;
    s.bend = c.n.w;
    s.drop = s.bend * phi(1.0);
    s.bound = sqrt(1.0 + s.drop * s.drop);
    set_shape(&s);
    hits[id.x] = intersect(s, c.e.xyz);
}

@compute @workgroup_size(64)
fn bends(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&cases) {
        return;
    }
    let c = cases[id.x];
    let colour = u32(c.e.x) << 24u | 0x5eedu;
    hits[id.x] = vec2<f32>(curvature_bend(c.p.w, c.n.w, colour, phi(1.0)), 0.0);
}
"#;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Case {
    p: [f32; 4],
    n: [f32; 4],
    e: [f32; 4],
}

/// The n-gons the ray casts are checked for: even and odd (the outline test's sign differs).
const SIDES: [u32; 2] = [6, 5];
const RINGS: u32 = 4;
const H: f64 = 1.0;

type V = [f64; 3];

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn scaled(a: V, k: f64) -> V {
    a.map(|x| x * k)
}

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn unit(a: V) -> V {
    scaled(a, 1.0 / dot(a, a).sqrt())
}

fn phi(r: f64) -> f64 {
    let q = r * r / (H * H);
    1.0 - (-q * q).exp()
}

/// phi linear between the rings.
fn phi_mesh(rho: f64) -> f64 {
    let k = ((rho * RINGS as f64).floor() as u32).min(RINGS - 1);
    let (r0, r1) = (k as f64 / RINGS as f64, (k + 1) as f64 / RINGS as f64);
    let t = (rho - r0) / (r1 - r0);
    phi(r0) + t * (phi(r1) - phi(r0))
}

/// The n-gon's basis, as set_shape in surfel.wgsl.
fn basis(n: V) -> (V, V) {
    let sgn = if n[2] >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sgn + n[2]);
    let b = n[0] * n[1] * a;
    (
        [1.0 + sgn * n[0] * n[0] * a, sgn * b, -sgn * n[0]],
        [b, sgn + n[1] * n[1] * a, -n[1]],
    )
}

/// The radial distance at which the `sides`-gon's outline lies in the direction of `c`.
fn outline(c: V, n: V, sides: u32) -> f64 {
    let (b1, b2) = basis(n);
    let half = std::f64::consts::PI / sides as f64;
    let theta = dot(c, b2).atan2(dot(c, b1)) + std::f64::consts::PI;
    let off = theta - 2.0 * half * (theta / (2.0 * half)).floor() - half;
    half.cos() / off.cos()
}

/// What the CPU march finds along a ray.
enum Expect {
    /// The first crossing of the surface, at this distance, well inside the n-gon.
    Hit(f64),
    /// No point of the ray comes near the surface inside the n-gon's circumcircle.
    Miss,
    /// Near the rim, or touching without crossing: either answer is right.
    Either,
}

fn expect(eye: V, e: V, p: V, radius: f64, n: V, bend: f64, sides: u32) -> Expect {
    let bound = (1.0 + (bend * phi(1.0)).powi(2)).sqrt() * radius;
    let tc = dot(sub(p, eye), e);
    let off = sub(sub(eye, p), scaled(e, -tc));
    let half_chord2 = bound * bound - dot(off, off);
    if half_chord2 <= 0.0 {
        return Expect::Miss;
    }
    let half_chord = half_chord2.sqrt();
    // Height over the surface (in radius units) and radial distance at distance t.
    let at = |t: f64| {
        let o = scaled(
            sub([eye[0] + t * e[0], eye[1] + t * e[1], eye[2] + t * e[2]], p),
            1.0 / radius,
        );
        let a = dot(o, n);
        let c = sub(o, scaled(n, a));
        let u = dot(c, c).sqrt();
        (a + bend * phi_mesh(u.min(1.0)), u, c)
    };
    let steps = 20_000;
    let (t0, t1) = (tc - half_chord, tc + half_chord);
    let mut near = f64::MAX;
    let mut prev = at(t0);
    for i in 1..=steps {
        let t = t0 + (t1 - t0) * i as f64 / steps as f64;
        let cur = at(t);
        if cur.1 <= 1.0 {
            near = near.min(cur.0.abs());
        }
        if (prev.0 <= 0.0) != (cur.0 <= 0.0) && (prev.1 <= 1.0 || cur.1 <= 1.0) {
            let (mut lo, mut hi) = (t - (t1 - t0) / steps as f64, t);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if (at(mid).0 <= 0.0) == (prev.0 <= 0.0) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let (_, u, c) = at(lo);
            let rim = outline(c, n, sides);
            if u < rim - 2e-3 {
                return if lo > 0.0 {
                    Expect::Hit(lo)
                } else {
                    Expect::Either
                };
            }
            if u <= rim + 2e-3 {
                return Expect::Either;
            }
        }
        prev = cur;
    }
    if near > 2e-3 {
        Expect::Miss
    } else {
        Expect::Either
    }
}

/// A deterministic source of numbers in [0, 1).
fn randoms() -> impl FnMut() -> f64 {
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Runs `entry` of KERNEL_WGSL compiled for `sides`-gons over `cases`, with `uniforms`; its
/// output per case.
fn run(
    entry: &'static str,
    sides: u32,
    uniforms: &SurfelUniforms,
    cases: &[Case],
) -> Vec<[f32; 2]> {
    let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
    let device = &ctx.device;
    let source = ShaderSource::new(
        "c-surfel casts",
        &[
            UNIFORMS_WGSL,
            FILTERS_WGSL,
            RANGE_SEARCH_WGSL,
            OCT16_WGSL,
            SURFEL_WGSL,
            CURVED_WGSL,
            KERNEL_WGSL,
        ],
    )
    .with_entry(entry)
    .with_constant("SIDES", sides as f64);
    let pipe = source.compute(device, None);
    let buffer = |contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents,
            usage,
        })
    };
    let surf = buffer(bytemuck::bytes_of(uniforms), wgpu::BufferUsages::UNIFORM);
    let input = buffer(bytemuck::cast_slice(cases), wgpu::BufferUsages::STORAGE);
    let hits = kernel_output(device, (cases.len() * 8) as u64);
    let g0 = bind(device, &pipe, 0, &[(1, surf.as_entire_binding())]);
    let g1 = bind(device, &pipe, 1, &[]);
    let g2 = bind(
        device,
        &pipe,
        2,
        &[
            (0, input.as_entire_binding()),
            (1, hits.as_entire_binding()),
        ],
    );
    let bytes = run_kernel(&ctx, &pipe, &[g0, g1, g2], cases.len(), &hits);
    bytemuck::cast_slice(&bytes).to_vec()
}

#[test]
fn c_surfel_ray_casts_match_a_march_over_the_surface() {
    let mut random = randoms();
    let mut sphere = || loop {
        let v = [
            random() * 2.0 - 1.0,
            random() * 2.0 - 1.0,
            random() * 2.0 - 1.0,
        ];
        if dot(v, v) <= 1.0 && dot(v, v) > 1e-6 {
            return v;
        }
    };
    let eye = [0.0, 0.0, 0.0];
    let mut cases = Vec::new();
    let mut rays = Vec::new();
    for case in 0..4000 {
        // The paper's c-surfel, and ones a curvature bends less (curvature_bend), down to
        // cones so flat that a careless quadratic loses them to rounding.
        let bend = [1.0, 0.3, 1e-2, 1e-3, 0.0][case % 5];
        let p = scaled(unit(sphere()), 10.0);
        let radius = 0.5;
        let n = unit(sphere());
        // Aimed anywhere in a box a third wider than the c-surfel's bound.
        let target = [0, 1, 2].map(|i| p[i] + sphere()[i] * radius * 1.9);
        let e = unit(sub(target, eye));
        let f = |v: V, w: f64| [v[0] as f32, v[1] as f32, v[2] as f32, w as f32];
        cases.push(Case {
            p: f(p, radius),
            n: f(n, bend),
            e: f(e, 0.0),
        });
        rays.push((p, radius, n, e, bend));
    }
    let uniforms = SurfelUniforms {
        eye: [0.0, 0.0, 0.0, 1.0],
        rings: RINGS,
        ring_phi: SurfelUniforms::ring_phi(H as f32, RINGS),
        h: H as f32,
        ..SurfelUniforms::zeroed()
    };
    for sides in SIDES {
        let got = run("cast_rays", sides, &uniforms, &cases);
        let (mut hit, mut missed) = (0, 0);
        for (k, (&(p, radius, n, e, bend), g)) in rays.iter().zip(got).enumerate() {
            match expect(eye, e, p, radius, n, bend, sides) {
                Expect::Hit(t) => {
                    hit += 1;
                    assert!(
                        g[0] > 0.0 && (g[0] as f64 - t).abs() < 2e-3 * radius,
                        "{sides} sides, case {k}: the surface is {t} along the ray, the cast says {g:?}"
                    );
                }
                Expect::Miss => {
                    missed += 1;
                    assert!(
                        g[0] < 0.0,
                        "{sides} sides, case {k}: the ray misses, the cast says {g:?}"
                    );
                }
                Expect::Either => {}
            }
        }
        // Enough of both to mean something.
        assert!(
            hit > 500 && missed > 500,
            "{sides} sides: {hit} hits and {missed} misses checked"
        );
    }
}

#[test]
fn a_c_surfel_bends_by_its_curvature_over_its_drawn_radius() {
    // The stored radius in p.w, the drawn radius in n.w, the colour's alpha byte in e.x.
    let scale = 0.8f32;
    let uniforms = SurfelUniforms {
        h: H as f32,
        curvature: scale,
        ..SurfelUniforms::zeroed()
    };
    let phi1 = phi(1.0) as f32;
    let mut cases = Vec::new();
    let mut want = Vec::new();
    for (stored, drawn, alpha) in [
        (0.5f32, 0.5f32, 64u32),
        (0.5, 2.0, 64),
        (2.0, 2.0, 255),
        (0.1, 0.4, 16),
        (1.0, 1.0, 0),
        (0.25, 8.0, 255),
    ] {
        // The rim drops kappa drawn / 2 radii, kappa stored = scale sqrt(alpha / 255).
        let kappa = scale * (alpha as f32 / 255.0).sqrt() / stored;
        want.push((0.5 * kappa * drawn / phi1).min(1.0));
        cases.push(Case {
            p: [0.0, 0.0, 0.0, stored],
            n: [0.0, 0.0, 1.0, drawn],
            e: [alpha as f32, 0.0, 0.0, 0.0],
        });
    }
    let got = run("bends", SIDES[0], &uniforms, &cases);
    for (k, (w, g)) in want.iter().zip(&got).enumerate() {
        assert!(
            (g[0] - w).abs() < 1e-4 * w.max(1e-3),
            "case {k}: bend {} for {w}",
            g[0]
        );
    }
    // Without a curvature every c-surfel bends as the paper's.
    let paper = run(
        "bends",
        SIDES[0],
        &SurfelUniforms {
            curvature: 0.0,
            ..uniforms
        },
        &cases,
    );
    assert!(paper.iter().all(|g| g[0] == 1.0), "{paper:?}");
}
