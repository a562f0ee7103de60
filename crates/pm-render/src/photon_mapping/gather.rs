//! Final gathering (Christensen 1999 sections 1.3 and 2.2): stratified,
//! cosine-distributed rays over the hemisphere whose hit points read the global
//! photon map, with a secondary gather for short rays, and the irradiance gradients
//! of Ward and Heckbert 1992 ("Irradiance Gradients") from the same rays.

use super::PhotonMapping;
use super::scratch::Scratch;
use crate::icache::Gather;
use crate::{Lookup, facing};
use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_estimate::{Filter, KnnParams};
use pm_format::PhotonRecord;
use pm_sampling::{Sampler, basis, mix64, unit_of};
use pm_scene::{Hit, MediumId};
use std::f32::consts::PI;
use std::sync::atomic::Ordering::Relaxed;

/// Most hidden photons one precomputed lookup tries before it misses.
const VISIBILITY_TESTS: u32 = 16;

/// How far a visibility test lifts the query point and the photon off their
/// surfaces, as a fraction of their distance.
const LIFT: f32 = 0.125;

/// Irradiance at a final-gather ray's hit point from the global map: the
/// precomputed irradiance of the nearest similar photon, or a k-nearest estimate.
pub(crate) fn lookup_irradiance<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    p: Vec3,
    n: Vec3,
    scratch: &mut Scratch,
) -> Rgb {
    let cfg = &ctx.cfg;
    ctx.counters.lookups.fetch_add(1, Relaxed);
    match cfg.lookup {
        Lookup::Precomputed => match &ctx.maps.irradiance {
            Some(tree) => {
                let max_d2 = cfg.max_radius_global * cfg.max_radius_global;
                // The photon must be visible from the query point: otherwise, near a
                // thin wall, a room with no photons of its own would borrow the
                // irradiance of the room next door (a coplanar floor passes the
                // normal test; tests/tests/suite/hard_scenes.rs), and the underside of
                // a light 2.6 mm below the ceiling would read the ceiling above it
                // (+150% indirect light; the differential checker's scene, issue 53).
                // The path runs from each point along its own normal, lifted by an
                // eighth of their distance, and across between the lifted points:
                // the lift clears the chord of a curved surface (the chord between
                // normals 43 degrees apart, the lookup's normal test with a stored
                // normal's error, sags a tenth of its length), and the legs along
                // the normals catch a parallel surface closer than the lift. A
                // photon in the query's plane needs no legs (a surface a gap away
                // is out of it), and none within a hair of the query a ray: most
                // lookups in a room of flat walls (one ray, not three: the cache
                // prepass 18% faster on cornell_spheres; BENCHMARKS.md).
                let near = 1e-3 * ctx.scene.bounds.diagonal();
                // The nearest similar photon is tested first, then the next; after
                // VISIBILITY_TESTS hidden ones the lookup misses, as when no candidate
                // is visible: among many curved objects, a lookup could try hundreds
                // (62% of a 1.46M-triangle scene's prepass; BENCHMARKS.md).
                let visible = |r: &G| {
                    let (q, nq) = (r.position(), r.normal());
                    let to_q = q - p;
                    let len = to_q.length();
                    let in_plane = n.dot(to_q).abs() <= 1e-4 * len + 1e-6 * p.abs().max(q.abs()).max_element();
                    if len == 0.0 || (in_plane && len < near) {
                        return true;
                    }
                    let lift = LIFT * len;
                    let (o, q_up) = (p + n * lift, q + nq * lift);
                    let d = q_up - o;
                    let across = d.length();
                    let scene = &ctx.scene;
                    // Index-matched boundaries (a fog box's walls, 1 mm off the
                    // floor) do not block: light passes them.
                    let open = |o, d, t| scene.transmittance_along(o, d, t, None) != Rgb::ZERO;
                    (in_plane
                        || open(scene.offset_origin(p, n, n), n, lift)
                            && open(scene.offset_origin(q, nq, nq), nq, lift))
                        && (across == 0.0 || open(o, d / across, across))
                };
                // A photon under a cover (in the gap above a light panel a few
                // millimetres below the ceiling, bright with trapped light) serves
                // only a query under one too: the ceiling just outside the panel
                // saw the gap's irradiance through the lift below (+5% indirect
                // light on the differential checker's scene 7 of seed 3, issue 53).
                // One ray, only when such a photon is met.
                let found = pm_estimate::precomputed_irradiance_where(
                    tree,
                    p,
                    n,
                    max_d2,
                    &mut scratch.rejected,
                    || crate::covered(ctx.scene, p, n),
                    visible,
                    VISIBILITY_TESTS,
                );
                match found {
                    Some((e, hit)) => {
                        ctx.counters.lookup_rank[(hit.rank as usize - 1).min(2)].fetch_add(1, Relaxed);
                        e
                    }
                    None => {
                        ctx.counters.lookup_misses.fetch_add(1, Relaxed);
                        Rgb::ZERO
                    }
                }
            }
            None => Rgb::ZERO,
        },
        Lookup::Exact => match &ctx.maps.global {
            Some(tree) => {
                let params = KnnParams {
                    k: cfg.k_global,
                    max_d2: cfg.max_radius_global * cfg.max_radius_global,
                    filter: Filter::None,
                };
                // As the precompute estimates at a photon (the gaps around the
                // surface, covers, the disc's share on it), with a turn of the
                // disc's probes from the point's bits.
                let surfaces = crate::SceneSurfaces { scene: ctx.scene, reach: cfg.max_radius_global };
                let bits = p.to_array().map(f32::to_bits);
                let turn = unit_of(mix64((bits[0] as u64) << 32 ^ (bits[1] as u64) << 16 ^ bits[2] as u64));
                let covered = || crate::covered(ctx.scene, p, n);
                pm_estimate::surface_irradiance(tree, Some(&surfaces), p, n, covered, turn, &params, &mut scratch.knn).e
            }
            None => Rgb::ZERO,
        },
    }
}

/// Radiance arriving at the gather origin along one gather ray, excluding emission
/// (direct light is sampled separately) and returning the first hit distance.
/// Specular surfaces are followed (up to the depth limit), and glossy ones after
/// their direct light is taken; at the first other hit the radiance is albedo / pi
/// x irradiance. A ray shorter than the secondary-gather
/// distance gets a small secondary gather there instead of a photon-map lookup.
/// The ray starts in medium `medium`: in a medium each segment attenuates what
/// lies beyond it and adds the light the volume map says scatters along it (every
/// volume photon: what arrives at the gather's surface through the medium is
/// indirect light, single scattering included); index-matched boundaries are
/// passed.
fn gather_radiance<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    o: Vec3,
    d: Vec3,
    medium: Option<MediumId>,
    s: &mut Sampler,
    secondary: bool,
    scratch: &mut Scratch,
) -> (Rgb, f32) {
    let scene = ctx.scene;
    let (mut o, mut d, mut medium) = (o, d, medium);
    let mut beta = Rgb::ONE;
    let mut l = Rgb::ZERO;
    let mut first_t = f32::INFINITY;
    let media = scene.has_media();
    // Follow specular surfaces as far as the eye paths may (through two nested glass
    // spheres a gather ray meets four interfaces before a diffuse surface).
    let (mut bounce, mut passed) = (0, 0u32);
    // How far the ray has run through index-matched boundaries before its first
    // bounce \[m\]: the distance that decides a secondary gather and the cache
    // record's radius is the origin's to the first surface that is not one (a fog
    // box's floor face 1 mm above the floor made every gather ray that passed it a
    // short one: 776,000 secondary gathers on a 16 x 16 cornell_fog).
    let mut run = 0.0f32;
    while bounce < ctx.cfg.max_depth.max(1) && passed < 1024 {
        let hit = scene.intersect(o, d, f32::INFINITY);
        if media && let Some(m) = scene.medium(medium).filter(|m| !m.is_clear()) {
            let t_seg = scene.segment_length(o, d, hit.as_ref());
            if m.scatters() {
                let seg = pm_estimate::Segment { o, d, t_max: t_seg, sigma_t: m.sigma_t() };
                l += beta * super::volume::gathered(ctx, &seg, m, s, scratch);
            }
            beta *= m.transmittance(t_seg);
        }
        let Some(hit) = hit else { return (l, first_t) };
        if let Some(tint) = scene.index_matched(&hit) {
            beta *= tint;
            medium = scene.medium_after(&hit, d, medium);
            let next = scene.offset_origin(hit.p, hit.ng, d);
            if bounce == 0 {
                run += (next - o).dot(d);
            }
            o = next;
            passed += 1;
            continue;
        }
        if bounce == 0 && first_t == f32::INFINITY {
            first_t = run + hit.t;
        }
        let bsdf = scene.bsdf(&hit);
        let glossy = bsdf.is_glossy();
        if bsdf.is_specular() || glossy {
            if glossy {
                // The light a glossy surface sends along the ray depends on where
                // it comes from: its direct light by light sampling (with the
                // BSDF's own samples weighed against them, which is why emission
                // is not counted further on), then one sample of its lobe,
                // followed on as a mirror's is. Read as albedo / pi x irradiance,
                // a rough metal slab on the floor sent the ceiling a tenth of the
                // light it reflects up from the lamp above it (the ceiling's
                // indirect light 35% dark in 8 x 8 blocks around the lamp: the
                // differential checker's seed 16654, scene 3).
                l += beta * ctx.light.direct(&hit, &bsdf, -d, s, 1, medium);
            }
            let u = s.next_2d();
            let uc = s.next_1d();
            let Some(bs) = bsdf.sample(-d, hit.ns, u, uc) else { return (l, first_t) };
            if glossy && !pm_scene::same_side(hit.ng, bs.wi, -d) {
                return (l, first_t);
            }
            beta *= bs.radiance_weight();
            if media {
                medium = scene.medium_after(&hit, bs.wi, medium);
            }
            o = ctx.scene.offset_origin(hit.p, hit.ng, bs.wi);
            d = bs.wi;
            bounce += 1;
            continue;
        }
        let n = facing(hit.ng, -d);
        let e = if secondary && bounce == 0 && first_t < ctx.cfg.secondary_distance && ctx.cfg.secondary_rays > 0 {
            ctx.counters.secondary_gathers.fetch_add(1, Relaxed);
            secondary_irradiance(ctx, &hit, n, medium, s, scratch)
        } else {
            lookup_irradiance(ctx, hit.p, n, scratch)
        };
        return (l + beta * bsdf.albedo(-d, hit.ns) * e / PI, first_t);
    }
    ctx.counters.terminated_paths.fetch_add(1, Relaxed);
    (l, first_t)
}

/// Indirect radiance a glossy surface ([`Bsdf::is_glossy`], or a dielectric's GGX
/// layer: [`Bsdf::layers`]) reflects toward `wo` [W sr^-1 m^-2]: `rays` directions
/// sampled from its BSDF, each weighted by
/// f cos / pdf and carrying what a final-gather ray along it finds
/// ([`gather_radiance`]: the photon maps at its first non-specular hit, emission
/// left out). Jensen's glossy term (2001, section 9.2): the irradiance cache and the
/// cosine-weighted gather assume the surface reflects all directions alike. Light
/// from the lights is the direct estimate's (its BSDF samples weighed against
/// light samples), and light from them through mirrors and glass the caustic
/// map's, so a gather ray that hits an emitter counts nothing.
pub(crate) fn glossy_gather<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    hit: &Hit,
    bsdf: &Bsdf,
    wo: Vec3,
    rays: u32,
    medium: Option<MediumId>,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let scene = ctx.scene;
    let rays = rays.max(1);
    ctx.counters.gather_rays.fetch_add(rays as u64, Relaxed);
    let mut sum = Rgb::ZERO;
    for _ in 0..rays {
        let u = s.next_2d();
        let uc = s.next_1d();
        let Some(bs) = bsdf.sample(wo, hit.ns, u, uc) else { continue };
        // A direction through the geometric surface (a shading normal's artefact)
        // finds nothing.
        if !pm_scene::same_side(hit.ng, bs.wi, wo) {
            continue;
        }
        let o = scene.offset_origin(hit.p, hit.ng, bs.wi);
        let m2 = if scene.has_media() { scene.medium_after(hit, bs.wi, medium) } else { medium };
        let (li, _) = gather_radiance(ctx, o, bs.wi, m2, s, true, scratch);
        sum += bs.radiance_weight() * li;
    }
    sum / rays as f32
}

/// Total irradiance at a point reached by a short gather ray: direct light by light
/// sampling plus a secondary gather of `secondary_rays` rays reading the photon map
/// (Jensen 1996; Christensen 1999 section 1.3: "we have found 12 to be sufficient").
fn secondary_irradiance<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    hit: &Hit,
    n: Vec3,
    medium: Option<MediumId>,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    // A Lambertian BSDF of albedo pi has f = 1, so the direct "radiance" it returns is
    // the direct irradiance.
    let unit = Bsdf::Lambert { rho: Rgb::splat(PI) };
    let mut h = *hit;
    h.ns = facing(hit.ns, n);
    let e_direct = ctx.light.direct(&h, &unit, n, s, 1, medium);
    let at = GatherPoint { x: hit.p, ns: h.ns, ng: n, medium };
    let g = final_gather(ctx, &at, ctx.cfg.secondary_rays, s, GatherFor::Secondary, scratch);
    e_direct + g.e
}

/// What a final gather is for: what it computes beyond the irradiance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum GatherFor {
    /// An irradiance-cache record: secondary gathers at short rays, and the
    /// gradients (Ward and Heckbert 1992).
    Record,
    /// An irradiance used once (a render's gather where no record reaches):
    /// secondary gathers, no gradients.
    Estimate,
    /// A secondary gather at a short ray's end: neither (its twelve rays' gradients,
    /// with the trigonometry of every ring and sector, were computed and dropped at
    /// a third of the cache prepass's gathers).
    Secondary,
}

/// Where a final gather looks from: a point, its shading and geometric normals
/// (both on the side being lit) and the medium it is in.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GatherPoint {
    /// The point \[m\].
    pub x: Vec3,
    /// Shading normal, on the lit side.
    pub ns: Vec3,
    /// Geometric normal, on the lit side.
    pub ng: Vec3,
    /// The medium around it (None: vacuum or the scene's world medium).
    pub medium: Option<MediumId>,
}

/// A final gather at `at` (`rays` rays): E = pi / (M N) sum L_jk over M x N strata with
/// sin^2 theta_j uniform in [j/M, (j+1)/M) and phi_k in [2 pi k / N, 2 pi (k+1) / N)
/// (cosine-weighted stratified sampling, Ward and Heckbert 1992).
pub(crate) fn final_gather<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    at: &GatherPoint,
    rays: u32,
    s: &mut Sampler,
    purpose: GatherFor,
    scratch: &mut Scratch,
) -> Gather {
    let GatherPoint { x, ns, ng, medium } = *at;
    let secondary = purpose != GatherFor::Secondary;
    let m = ((rays as f32 / PI).sqrt().round() as usize).max(1);
    let n = ((rays as f32 / m as f32).round() as usize).max(1);
    ctx.counters.gather_rays.fetch_add((m * n) as u64, Relaxed);
    let (t, b) = basis(ns);
    let world = |l: Vec3| t * l.x + b * l.y + ns * l.z;
    // Each stratum's radiance and hit distance, kept for the gradients.
    let keep = if purpose == GatherFor::Record { m * n } else { 0 };
    let mut l = vec![Rgb::ZERO; keep];
    let mut r = vec![f32::INFINITY; keep];
    let mut sum = Rgb::ZERO;
    let mut inv_r = 0.0f64;
    let mut grad_r = [Vec3::ZERO; 3];
    for j in 0..m {
        for k in 0..n {
            let u = s.next_2d();
            let sin2 = (j as f32 + u.x) / m as f32;
            let (sin_t, cos_t) = (sin2.sqrt(), (1.0 - sin2).max(0.0).sqrt());
            let phi = 2.0 * PI * (k as f32 + u.y) / n as f32;
            let (sin_phi, cos_phi) = (phi.sin(), phi.cos());
            let dir = world(Vec3::new(sin_t * cos_phi, sin_t * sin_phi, cos_t));
            let (mut li, mut ri) = (Rgb::ZERO, f32::INFINITY);
            if dir.dot(ng) > 0.0 {
                let o = ctx.scene.offset_origin(x, ng, dir);
                (li, ri) = gather_radiance(ctx, o, dir, medium, s, secondary, scratch);
            }
            sum += li;
            if ri.is_finite() && ri > 0.0 {
                inv_r += 1.0 / ri as f64;
            }
            if keep == 0 {
                continue;
            }
            l[j * n + k] = li;
            r[j * n + k] = ri;
            // Rotational gradient: sum of -tan(theta) L v(phi), v the tangent direction
            // perpendicular to phi.
            let tan_t = if cos_t > 1e-6 { sin_t / cos_t } else { 0.0 };
            let v = world(Vec3::new(-sin_phi, cos_phi, 0.0)) * -tan_t;
            for c in 0..3 {
                grad_r[c] += v * li[c];
            }
        }
    }
    let norm = PI / (m * n) as f32;
    let r_harmonic = if inv_r > 0.0 { ((m * n) as f64 / inv_r) as f32 } else { f32::INFINITY };
    if keep == 0 {
        return Gather { e: sum * norm, r_harmonic, grad_t: [Vec3::ZERO; 3], grad_r };
    }
    for g in &mut grad_r {
        *g *= norm;
    }
    // Translational gradient (Ward and Heckbert 1992, eq. 9 in Krivanek et al.'s
    // notation): radiance differences across the stratum boundaries, weighted by the
    // boundary's projected size and divided by the nearer hit distance. The angles
    // depend on the ring j or the sector k alone: computed once each (their
    // trigonometry, redone for every stratum, was a tenth of a gather's time).
    let mut grad_t = [Vec3::ZERO; 3];
    let theta_at = |q: f32| (q / m as f32).sqrt().clamp(0.0, 1.0).asin();
    // Per ring: the coefficient of the boundary with the ring inside it (before the
    // division by the distance), and of the boundaries between its sectors.
    let rings: Vec<(f32, Option<(f32, f32)>)> = (0..m)
        .map(|j| {
            let (th, th_hi, th_mid) = (theta_at(j as f32), theta_at(j as f32 + 1.0), theta_at(j as f32 + 0.5));
            let inner = 2.0 * PI / n as f32 * th.sin() * th.cos() * th.cos();
            let sectors = (th_mid.sin() > 0.0).then(|| (th.cos() - th_hi.cos(), th_mid.sin()));
            (inner, sectors)
        })
        .collect();
    for k in 0..n {
        let phi_c = 2.0 * PI * (k as f32 + 0.5) / n as f32;
        let phi_b = 2.0 * PI * k as f32 / n as f32;
        let u_k = world(Vec3::new(phi_c.cos(), phi_c.sin(), 0.0));
        let v_k = world(Vec3::new(-phi_b.sin(), phi_b.cos(), 0.0));
        let k_prev = (k + n - 1) % n;
        for (j, &(inner, sectors)) in rings.iter().enumerate() {
            if j > 0 {
                let rmin = r[j * n + k].min(r[(j - 1) * n + k]);
                if rmin.is_finite() && rmin > 0.0 {
                    let coeff = inner / rmin;
                    let dl = l[j * n + k] - l[(j - 1) * n + k];
                    for c in 0..3 {
                        grad_t[c] += u_k * (coeff * dl[c]);
                    }
                }
            }
            if n > 1 {
                let rmin = r[j * n + k].min(r[j * n + k_prev]);
                if let Some((num, den)) = sectors
                    && rmin.is_finite()
                    && rmin > 0.0
                {
                    let coeff = num / (den * rmin);
                    let dl = l[j * n + k] - l[j * n + k_prev];
                    for c in 0..3 {
                        grad_t[c] += v_k * (coeff * dl[c]);
                    }
                }
            }
        }
    }
    Gather { e: sum * norm, r_harmonic, grad_t, grad_r }
}
