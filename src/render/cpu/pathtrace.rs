//! kernels/render/textures.cl, materials.cl, lights.cl, film.cl and pathtrace.cl in Rust: the
//! megakernel's algorithm (Alg. 1) on the CPU, one pixel at a time, with rayon across pixels.

use std::f32::consts::PI;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::rng::*;
use super::sampling::*;
use crate::arrays::SceneArrays;
use crate::arrays::trace::{Hit, Prim, intersect_closest, occluded};
use crate::geometry::{offset_ray_origin, ray_sphere};
use crate::layout::*;

/// Which compile-time switches of the kernel the reference follows.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceOptions {
    pub russian_roulette: bool,
    pub next_event_estimation: bool,
}

fn texel_fetch(s: &SceneArrays, t: &TextureInfo, x: i32, y: i32) -> Vec4 {
    let (w, h) = (t.width as i32, t.height as i32);
    let x = x.rem_euclid(w);
    let y = y.rem_euclid(h);
    Vec4::from_array(crate::arrays::texels::texel(
        &s.texels,
        t,
        (y * w + x) as u32,
    ))
}

pub fn texture_bilinear(s: &SceneArrays, index: u32, uv: Vec2) -> Vec4 {
    let t = &s.textures[index as usize];
    let mut st = uv * Vec2::from(t.uv_scale.0) + Vec2::from(t.uv_shift.0);
    st -= st.floor();
    let x = st.x * t.width as f32 - 0.5;
    let y = (1.0 - st.y) * t.height as f32 - 0.5;
    let (fx, fy) = (x.floor(), y.floor());
    let (ax, ay) = (x - fx, y - fy);
    let (x0, y0) = (fx as i32, fy as i32);
    let a = texel_fetch(s, t, x0, y0);
    let b = texel_fetch(s, t, x0 + 1, y0);
    let c = texel_fetch(s, t, x0, y0 + 1);
    let d = texel_fetch(s, t, x0 + 1, y0 + 1);
    (a * (1.0 - ax) + b * ax) * (1.0 - ay) + (c * (1.0 - ax) + d * ax) * ay
}

pub fn environment_radiance(s: &SceneArrays, d: Vec3) -> Vec3 {
    let p = &s.params;
    let mut radiance = p.env_radiance.xyz();
    if p.env_texture >= 0 {
        let u = 0.5 + d.x.atan2(-d.z) * (0.5 / PI);
        let v = 0.5 + d.y.clamp(-1.0, 1.0).asin() / PI;
        let uv = Vec2::new(u, v) * Vec2::new(p.env_uv.0[0], p.env_uv.0[1])
            + Vec2::new(p.env_uv.0[2], p.env_uv.0[3]);
        radiance *= texture_bilinear(s, p.env_texture as u32, uv).truncate();
    }
    radiance
}

pub struct Surface {
    pub p: Vec3,
    pub ng: Vec3,
    pub ns: Vec3,
    pub uv: Vec2,
    pub material: u32,
    pub entering: bool,
}

pub fn surface_at(s: &SceneArrays, hit: &Hit, o: Vec3, d: Vec3) -> Surface {
    let p = o + hit.t * d;
    let (ng_raw, ns_raw, uv, material) = match hit.prim {
        Prim::Triangle(k) => {
            let g = &s.tri_geom[k as usize];
            let sh = &s.tri_shading[k as usize];
            let w = 1.0 - hit.u - hit.v;
            let ng = (g.v1.xyz() - g.v0.xyz())
                .cross(g.v2.xyz() - g.v0.xyz())
                .normalize();
            let ns = (w * sh.n0.xyz() + hit.u * sh.n1.xyz() + hit.v * sh.n2.xyz()).normalize();
            let uv = w * Vec2::from(sh.uv0.0)
                + hit.u * Vec2::from(sh.uv1.0)
                + hit.v * Vec2::from(sh.uv2.0);
            (ng, ns, uv, sh.material)
        }
        Prim::Sphere(i) => {
            let sp = &s.spheres[i as usize];
            let ng = (p - Vec3::from(sp.center)).normalize();
            let uv = Vec2::new(
                0.5 + ng.x.atan2(-ng.z) * (0.5 / PI),
                0.5 + ng.y.clamp(-1.0, 1.0).asin() / PI,
            );
            (ng, ng, uv, sp.material)
        }
    };
    let entering = d.dot(ng_raw) < 0.0;
    let ng = if entering { ng_raw } else { -ng_raw };
    let ns = if ns_raw.dot(ng) < 0.0 {
        -ns_raw
    } else {
        ns_raw
    };
    Surface {
        p,
        ng,
        ns,
        uv,
        material,
        entering,
    }
}

pub fn surface_albedo(s: &SceneArrays, sf: &Surface) -> Vec3 {
    let m = &s.materials[sf.material as usize];
    let c = m.color.xyz();
    if m.kind == MATERIAL_GLASS {
        return m.color2.xyz();
    }
    if m.kind == MATERIAL_EMITTER {
        let e = m.emission.xyz();
        let mx = e.max_element();
        return if mx > 0.0 { e / mx } else { Vec3::ZERO };
    }
    if m.kind == MATERIAL_DIFFUSE && m.texture >= 0 {
        return c * texture_bilinear(s, m.texture as u32, sf.uv).truncate();
    }
    c
}

pub struct Scatter {
    pub direction: Vec3,
    pub weight: Vec3,
    pub offset_normal: Vec3,
    pub specular: bool,
    pub absorbed: bool,
}

pub fn reflect_dir(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

pub fn scatter(
    s: &SceneArrays,
    sf: &Surface,
    d: Vec3,
    albedo: Vec3,
    key: u32,
    bounce: u32,
) -> Scatter {
    let m = &s.materials[sf.material as usize];
    let mut sc = Scatter {
        direction: d,
        weight: albedo,
        offset_normal: sf.ng,
        specular: true,
        absorbed: false,
    };
    let r1 = rng_uniform(key, bounce, DIM_BSDF_U);
    let r2 = rng_uniform(key, bounce, DIM_BSDF_V);
    match m.kind {
        MATERIAL_DIFFUSE => {
            sc.direction = sample_diffuse(r1, r2, sf.ns);
            sc.specular = false;
            sc.absorbed = sc.direction.dot(sf.ng) <= 0.0;
        }
        MATERIAL_SPECULAR => {
            sc.direction = reflect_dir(d, sf.ns);
            sc.absorbed = sc.direction.dot(sf.ng) <= 0.0;
        }
        MATERIAL_METAL => {
            sc.direction = sample_phong_lobe(r1, r2, reflect_dir(d, sf.ns), m.exponent);
            sc.absorbed = sc.direction.dot(sf.ng) <= 0.0;
        }
        MATERIAL_GLASS => {
            let (eta_i, eta_t) = if sf.entering {
                (m.ior_outside, m.ior_inside)
            } else {
                (m.ior_inside, m.ior_outside)
            };
            if eta_i == eta_t {
                sc.weight = m.color2.xyz();
                sc.offset_normal = -sf.ng;
                return sc;
            }
            let cos_i = (-d.dot(sf.ns)).min(1.0);
            let eta = eta_i / eta_t;
            let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
            let reflected = reflect_dir(d, sf.ns);
            if sin2_t >= 1.0 {
                sc.direction = reflected;
                sc.weight = m.color.xyz();
                return sc;
            }
            let cos_t = (1.0 - sin2_t).sqrt();
            let mut r0 = (eta_i - eta_t) / (eta_i + eta_t);
            r0 *= r0;
            let c = if eta_i <= eta_t { cos_i } else { cos_t };
            let k = 1.0 - c;
            let reflectance = r0 + (1.0 - r0) * k * k * k * k * k;
            if rng_uniform(key, bounce, DIM_BSDF_LOBE) < reflectance {
                sc.direction = reflected;
                sc.weight = m.color.xyz();
            } else {
                sc.direction = (eta * d + (eta * cos_i - cos_t) * sf.ns).normalize();
                sc.weight = m.color2.xyz();
                sc.offset_normal = -sf.ng;
            }
        }
        _ => sc.absorbed = true,
    }
    sc
}

fn select_light(s: &SceneArrays, u: f32) -> usize {
    let (mut lo, mut hi) = (0usize, s.params.light_count as usize - 1);
    while lo < hi {
        let mid = (lo + hi) >> 1;
        if u < s.light_cdf[mid] {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

pub const SHADOW_RAY_SHORTEN: f32 = 0.9999;

/// kernels/render/lights.cl sample_direct_light: the estimate, and the index of the light
/// chosen.
pub fn sample_direct_light(
    s: &SceneArrays,
    surface_p: Vec3,
    ng: Vec3,
    ns: Vec3,
    key: u32,
    bounce: u32,
    rays: &mut u32,
) -> (Vec3, u32) {
    let index = select_light(s, rng_uniform(key, bounce, DIM_LIGHT_SELECT));
    (
        direct_from(s, index, surface_p, ng, ns, key, bounce, rays),
        index as u32,
    )
}

#[allow(clippy::too_many_arguments)]
fn direct_from(
    s: &SceneArrays,
    index: usize,
    surface_p: Vec3,
    ng: Vec3,
    ns: Vec3,
    key: u32,
    bounce: u32,
    rays: &mut u32,
) -> Vec3 {
    let p = offset_ray_origin(surface_p, ng, s.params.scene_size);
    let light = &s.lights[index];
    let r1 = rng_uniform(key, bounce, DIM_LIGHT_U);
    let r2 = rng_uniform(key, bounce, DIM_LIGHT_V);
    let (dir, dist, inv_pdf);
    if light.kind == LIGHT_SPHERE {
        let c = light.p0.xyz();
        let r = light.p0.0[3];
        let to_c = c - p;
        let d2 = to_c.dot(to_c);
        let r2s = r * r;
        if d2 <= r2s {
            return Vec3::ZERO;
        }
        let dc = d2.sqrt();
        let sin2_max = r2s / d2;
        let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
        let one_minus_cos_max = sin2_max / (1.0 + cos_max);
        dir = sample_cone(r1, r2, to_c / dc, one_minus_cos_max);
        dist = ray_sphere(p, dir, c, r, 0.0, f32::INFINITY).unwrap_or(dc);
        inv_pdf = 2.0 * PI * one_minus_cos_max;
    } else {
        let b = sample_triangle(r1, r2);
        let (v0, v1, v2) = (light.p0.xyz(), light.p1.xyz(), light.p2.xyz());
        let q = v0 + b.x * (v1 - v0) + b.y * (v2 - v0);
        let to_q = q - p;
        let d2 = to_q.dot(to_q);
        if !(d2 > 0.0) {
            return Vec3::ZERO;
        }
        dist = d2.sqrt();
        dir = to_q / dist;
        let nl = (v1 - v0).cross(v2 - v0).normalize();
        let cos_l = -nl.dot(dir);
        if cos_l <= 0.0 {
            return Vec3::ZERO;
        }
        inv_pdf = cos_l * light.area / d2;
    }
    let cos_s = ns.dot(dir);
    if cos_s <= 0.0 || ng.dot(dir) <= 0.0 {
        return Vec3::ZERO;
    }
    *rays += 1;
    if occluded(s, p, dir, dist * SHADOW_RAY_SHORTEN) {
        return Vec3::ZERO;
    }
    light.emission.xyz() * (cos_s * inv_pdf / light.pmf)
}

/// What one path sample leaves behind (kernels/render/film.cl PathSample).
#[derive(Clone, Copy, Debug)]
pub struct PathSample {
    pub direct: Vec3,
    pub indirect: Vec3,
    /// Every contribution, whatever its bucket (not in the kernel): direct + indirect must
    /// equal it, which tests/statistics.rs checks against the kernel's split.
    pub total: Vec3,
    pub depth: f32,
    pub normal: Vec3,
    pub albedo: Vec3,
    pub albedo2: Vec3,
    pub direction: Vec3,
    /// The light the path brought to its first surface straight from the shadow light, when
    /// that surface is the pixel centre's receiver.
    pub shadow_direct: Vec3,
    /// Albedo × the shadow light's unoccluded term at the first hit, when that is the
    /// receiver (ShadowTerms.unshadowed).
    pub shadow_unshadowed: Vec3,
    /// The first hit is a diffuse point of the receiver's object (kernels/render/film.cl
    /// PathSample.receiver, one plane).
    pub receiver: bool,
    /// The light of an emitter the camera ray hit, part of `direct` (kernels/render/film.cl
    /// PathSample.emitted, the emission output).
    pub emitted: Vec3,
    /// The camera ray hit an emitter (front or back).
    pub on_emitter: bool,
}

impl PathSample {
    pub fn empty() -> Self {
        PathSample {
            direct: Vec3::ZERO,
            indirect: Vec3::ZERO,
            total: Vec3::ZERO,
            depth: SKY_DEPTH,
            normal: Vec3::ZERO,
            albedo: Vec3::ZERO,
            albedo2: Vec3::ZERO,
            direction: Vec3::ZERO,
            shadow_direct: Vec3::ZERO,
            shadow_unshadowed: Vec3::ZERO,
            receiver: false,
            emitted: Vec3::ZERO,
            on_emitter: false,
        }
    }

    fn add_light(&mut self, bounce: u32, value: Vec3) {
        self.total += value;
        if bounce <= 1 {
            self.direct += value;
        } else {
            self.indirect += value;
        }
    }

    pub fn to_array(&self) -> [f32; 16] {
        let (a, b, n, c, e) = (
            self.direct,
            self.indirect,
            self.normal,
            self.albedo,
            self.albedo2,
        );
        [
            a.x, a.y, a.z, b.x, b.y, b.z, self.depth, n.x, n.y, n.z, c.x, c.y, c.z, e.x, e.y, e.z,
        ]
    }
}

/// Whose shadow terms a path sample records (kernels/render/pathtrace.cl): the light's, when
/// the first hit is on `object`, the pixel centre's receiver.
#[derive(Clone, Copy, Debug)]
pub struct ShadowTarget {
    /// Index into the light list; u32::MAX: none.
    pub light: u32,
    /// The receiver's object (kernels/render/shadows.cl `hit_object`); NaN: none.
    pub object: f32,
}

impl ShadowTarget {
    pub const NONE: ShadowTarget = ShadowTarget {
        light: u32::MAX,
        object: f32::NAN,
    };
}

/// Algorithm 1 for one sample (kernels/render/pathtrace.cl trace_path).
/// Alg. 1 lines 5-11: from rr_depth on, whether the path goes on (its throughput divided by
/// the survival probability, max component capped at 0.95); without Russian roulette it ends
/// there.
pub fn survives(
    s: &SceneArrays,
    opt: ReferenceOptions,
    throughput: &mut Vec3,
    key: u32,
    bounce: u32,
) -> bool {
    if bounce < s.params.rr_depth {
        return true;
    }
    if !opt.russian_roulette {
        return false;
    }
    let survive = 0.95f32.min(throughput.max_element());
    if !(rng_uniform(key, bounce, DIM_RUSSIAN_ROULETTE) < survive) {
        return false;
    }
    *throughput /= survive;
    true
}

pub fn trace_path(
    s: &SceneArrays,
    opt: ReferenceOptions,
    x: u32,
    y: u32,
    key: u32,
    rays: &mut u32,
    target: ShadowTarget,
) -> PathSample {
    let (o, d) = camera_ray(&s.params, x, y, key);
    trace_path_from(s, opt, o, d, key, rays, target)
}

/// The same from a given camera ray (kernels/render/pathtrace.cl trace_path_from).
pub fn trace_path_from(
    s: &SceneArrays,
    opt: ReferenceOptions,
    o: Vec3,
    d: Vec3,
    key: u32,
    rays: &mut u32,
    target: ShadowTarget,
) -> PathSample {
    let params = &s.params;
    let mut ps = PathSample::empty();
    let (mut o, mut d) = (o, d);
    let mut throughput = Vec3::ONE;
    let mut count_emission = true;
    let mut want_albedo2 = true;
    let mut on_receiver = false;
    let has_lights = params.light_count > 0;
    let shadow_light = target.light;
    let shadow = (shadow_light < params.light_count).then(|| &s.lights[shadow_light as usize]);
    for bounce in 0..params.max_vertices {
        if !survives(s, opt, &mut throughput, key, bounce) {
            break;
        }
        *rays += 1;
        let Some(hit) = intersect_closest(s, o, d, f32::INFINITY) else {
            ps.add_light(bounce, throughput * environment_radiance(s, d));
            break;
        };
        let sf = surface_at(s, &hit, o, d);
        let m = &s.materials[sf.material as usize];
        if m.kind == MATERIAL_EMITTER {
            if count_emission && sf.entering {
                ps.add_light(bounce, throughput * m.emission.xyz());
                if bounce == 0 {
                    ps.emitted = throughput * m.emission.xyz();
                }
                let light = match hit.prim {
                    Prim::Triangle(k) => s.tri_shading[k as usize].light,
                    Prim::Sphere(i) => s.spheres[i as usize].light,
                };
                if bounce == 1 && on_receiver && light >= 0 && light as u32 == shadow_light {
                    ps.shadow_direct += throughput * m.emission.xyz();
                }
            }
            if bounce == 0 {
                ps.depth = hit.t;
                ps.normal = sf.ns;
                ps.albedo = surface_albedo(s, &sf);
                ps.on_emitter = true;
            }
            break;
        }
        let albedo = surface_albedo(s, &sf);
        if bounce == 0 {
            ps.depth = hit.t;
            ps.normal = sf.ns;
            ps.albedo = albedo;
        } else if want_albedo2 && m.kind == MATERIAL_DIFFUSE {
            ps.albedo2 = albedo;
            want_albedo2 = false;
        }
        if shadow.is_some()
            && bounce == 0
            && m.kind == MATERIAL_DIFFUSE
            && super::shadows::hit_object(s, &hit) == target.object
        {
            on_receiver = true;
            ps.receiver = true;
            if let Some(light) = shadow {
                ps.shadow_unshadowed =
                    albedo * super::shadows::shadow_unshadowed(light, sf.p, sf.ns);
            }
        }
        if has_lights && opt.next_event_estimation && m.kind == MATERIAL_DIFFUSE {
            let (li, chosen) = sample_direct_light(s, sf.p, sf.ng, sf.ns, key, bounce, rays);
            ps.add_light(bounce + 1, throughput * albedo * (1.0 / PI) * li);
            if bounce == 0 && on_receiver && chosen == shadow_light {
                ps.shadow_direct += throughput * albedo * (1.0 / PI) * li;
            }
        }
        let sc = scatter(s, &sf, d, albedo, key, bounce);
        if bounce == 0 && !sc.absorbed {
            ps.direction = sc.direction;
        }
        if sc.absorbed {
            break;
        }
        throughput *= sc.weight;
        if opt.next_event_estimation {
            count_emission = sc.specular;
        }
        o = offset_ray_origin(sf.p, sc.offset_normal, params.scene_size);
        d = sc.direction;
    }
    let limit = params.sample_clamp;
    if limit > 0.0 {
        let peak = (ps.direct + ps.indirect).max_element();
        if peak > limit {
            let k = limit / peak;
            ps.direct *= k;
            ps.indirect *= k;
            ps.total *= k;
            ps.shadow_direct *= k;
            ps.emitted *= k;
        }
    }
    ps
}

/// Renders samples [sample_base, sample_base + count) into `means` (FilterVector lanes, one
/// [f32; 16] per pixel) and `shifts` (DepthShift: K and the mean of depth - K), exactly as
/// kernels/render/film.cl folds them without variances (eq. 6.5), for a render of the samples
/// from `range_first` on (kernels/render/pathtrace.cl): sample `range_first` is its first, whose
/// depth is K. Returns rays traced.
pub fn render(
    s: &SceneArrays,
    opt: ReferenceOptions,
    means: &mut [[f32; 16]],
    shifts: &mut [[f32; 2]],
    range_first: u32,
    sample_base: u32,
    count: u32,
) -> u64 {
    let w = s.params.image_width;
    means
        .par_iter_mut()
        .zip(shifts.par_iter_mut())
        .enumerate()
        .map(|(pixel, (mean, shift))| {
            let (x, y) = (pixel as u32 % w, pixel as u32 / w);
            let mut rays = 0u32;
            for k in 0..count {
                let sample = sample_base + k;
                let key = rng_sample_key(s.params.seed, pixel as u32, sample);
                let x16 = trace_path(s, opt, x, y, key, &mut rays, ShadowTarget::NONE).to_array();
                let n = (sample - range_first + 1) as f32;
                for (i, (m, v)) in mean.iter_mut().zip(x16).enumerate() {
                    if i == DEPTH_LANE {
                        if sample == range_first {
                            *shift = [v, 0.0];
                        }
                        shift[1] += ((v - shift[0]) - shift[1]) / n;
                        *m = shift[0] + shift[1];
                    } else {
                        *m += (v - *m) / n;
                    }
                }
            }
            rays as u64
        })
        .sum()
}

/// The depth lane of [`PathSample::to_array`] (FilterVector.depth).
const DEPTH_LANE: usize = 6;
