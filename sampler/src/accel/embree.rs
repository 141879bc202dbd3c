//! A small binding to Intel Embree 3 (Debian's `libembree-dev`), compiled
//! only with the `embree` cargo feature: `holodeck bench tracer --embree`
//! traces the same rays through Embree in the same process, so the two
//! tracers are compared on one machine state, triangle for triangle.
//!
//! Only what the comparison needs: one triangle mesh per scene, built at
//! Embree's high quality, single rays (`rtcIntersect1`) and packets of eight
//! (`rtcIntersect8`).

use std::ffi::{c_char, c_int, c_uint, c_void};
use std::ptr::{null, null_mut};

use crate::accel::{Hit, RayCaster};
use crate::geom::Ray;
use glam::Vec3;

const RTC_GEOMETRY_TYPE_TRIANGLE: c_int = 0;
const RTC_BUFFER_TYPE_INDEX: c_int = 0;
const RTC_BUFFER_TYPE_VERTEX: c_int = 1;
const RTC_FORMAT_UINT3: c_int = 0x5003;
const RTC_FORMAT_FLOAT3: c_int = 0x9003;
const RTC_BUILD_QUALITY_HIGH: c_int = 2;
const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: c_uint = 0;
const RTC_INTERSECT_CONTEXT_FLAG_COHERENT: c_uint = 1;
const RTC_INVALID_GEOMETRY_ID: c_uint = u32::MAX;

/// `struct RTCIntersectContext` with `RTC_MAX_INSTANCE_LEVEL_COUNT` 1 and no
/// minimum width, as Debian builds it.
#[repr(C)]
struct IntersectContext {
    flags: c_uint,
    filter: *const c_void,
    inst_id: [c_uint; 1],
}

impl IntersectContext {
    /// What `rtcInitIntersectContext` (an inline function in the header) does.
    fn new(coherent: bool) -> IntersectContext {
        IntersectContext {
            flags: if coherent {
                RTC_INTERSECT_CONTEXT_FLAG_COHERENT
            } else {
                RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT
            },
            filter: null(),
            inst_id: [RTC_INVALID_GEOMETRY_ID],
        }
    }
}

/// `struct RTCRayHit`: `RTCRay` then `RTCHit`, each 16-byte aligned.
#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
struct RayHit1 {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: c_uint,
    id: c_uint,
    flags: c_uint,
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: c_uint,
    geom_id: c_uint,
    inst_id: [c_uint; 1],
}

/// The lane mask `rtcIntersect8` takes: -1 for lanes to trace, 0 for the
/// rest, 32-byte aligned as Embree loads it (an array of `int` alone is
/// 4-byte aligned and faults where it happens to straddle).
#[repr(C, align(32))]
struct Valid8([c_int; 8]);

/// `struct RTCRayHit8`: structure of arrays, 32-byte aligned.
#[repr(C, align(32))]
#[derive(Clone, Copy, Default)]
struct RayHit8 {
    org_x: [f32; 8],
    org_y: [f32; 8],
    org_z: [f32; 8],
    tnear: [f32; 8],
    dir_x: [f32; 8],
    dir_y: [f32; 8],
    dir_z: [f32; 8],
    time: [f32; 8],
    tfar: [f32; 8],
    mask: [c_uint; 8],
    id: [c_uint; 8],
    flags: [c_uint; 8],
    ng_x: [f32; 8],
    ng_y: [f32; 8],
    ng_z: [f32; 8],
    u: [f32; 8],
    v: [f32; 8],
    prim_id: [c_uint; 8],
    geom_id: [c_uint; 8],
    inst_id: [c_uint; 8],
}

#[link(name = "embree3")]
extern "C" {
    fn rtcNewDevice(config: *const c_char) -> *mut c_void;
    fn rtcReleaseDevice(device: *mut c_void);
    fn rtcGetDeviceError(device: *mut c_void) -> c_int;
    fn rtcNewScene(device: *mut c_void) -> *mut c_void;
    fn rtcSetSceneBuildQuality(scene: *mut c_void, quality: c_int);
    fn rtcCommitScene(scene: *mut c_void);
    fn rtcReleaseScene(scene: *mut c_void);
    fn rtcNewGeometry(device: *mut c_void, kind: c_int) -> *mut c_void;
    fn rtcSetGeometryBuildQuality(geometry: *mut c_void, quality: c_int);
    fn rtcSetNewGeometryBuffer(
        geometry: *mut c_void,
        kind: c_int,
        slot: c_uint,
        format: c_int,
        stride: usize,
        count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: *mut c_void);
    fn rtcAttachGeometry(scene: *mut c_void, geometry: *mut c_void) -> c_uint;
    fn rtcReleaseGeometry(geometry: *mut c_void);
    fn rtcIntersect1(scene: *mut c_void, context: *mut IntersectContext, rayhit: *mut RayHit1);
    // Takes an `RTCRay`, the first member of `RTCRayHit`: a `RayHit1`'s
    // leading fields are laid out as one.
    fn rtcOccluded1(scene: *mut c_void, context: *mut IntersectContext, ray: *mut RayHit1);
    fn rtcIntersect8(valid: *const c_int, scene: *mut c_void, context: *mut IntersectContext, rayhit: *mut RayHit8);
}

/// Why Embree could not take the scene.
#[derive(Debug, thiserror::Error)]
pub enum EmbreeError {
    /// `rtcNewDevice` failed (the library is there but would not start).
    #[error("Embree would not create a device")]
    Device,
    /// A call failed with Embree's error code.
    #[error("Embree failed while {what} (error code {code})")]
    Call {
        /// What was being done.
        what: &'static str,
        /// `RTCError`.
        code: i32,
    },
    /// More triangles or vertices than Embree's 32-bit indices hold.
    #[error("{0} is more than Embree's 32-bit indices hold")]
    TooBig(String),
}

/// One triangle mesh in an Embree scene, ready for rays.
pub struct Embree {
    device: *mut c_void,
    scene: *mut c_void,
}

// SAFETY: Embree's committed scenes may be traced from any thread; the handles
// are only released in `drop`.
unsafe impl Send for Embree {}
unsafe impl Sync for Embree {}

impl Embree {
    /// Builds Embree's BVH over the triangles (indices into `positions`), at
    /// high build quality, with Embree's default threads.
    pub fn new(positions: &[Vec3], triangles: impl ExactSizeIterator<Item = [u32; 3]>) -> Result<Embree, EmbreeError> {
        if u32::try_from(positions.len()).is_err() {
            return Err(EmbreeError::TooBig(format!("{} vertices", positions.len())));
        }
        let count = triangles.len();
        if u32::try_from(count).is_err() {
            return Err(EmbreeError::TooBig(format!("{count} triangles")));
        }
        // SAFETY: a null config asks for the defaults.
        let device = unsafe { rtcNewDevice(null()) };
        if device.is_null() {
            return Err(EmbreeError::Device);
        }
        // From here on, `drop` releases what exists.
        let mut e = Embree {
            device,
            scene: null_mut(),
        };
        let check = |what: &'static str| {
            // SAFETY: a live device.
            let code = unsafe { rtcGetDeviceError(device) };
            if code == 0 {
                Ok(())
            } else {
                Err(EmbreeError::Call { what, code })
            }
        };
        // SAFETY: every pointer below comes from the Embree call before it and
        // is checked; the buffers Embree hands out have room for `count` items
        // of the stride asked for (plus Embree's own padding).
        unsafe {
            e.scene = rtcNewScene(device);
            check("creating the scene")?;
            rtcSetSceneBuildQuality(e.scene, RTC_BUILD_QUALITY_HIGH);
            let geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
            check("creating the mesh")?;
            rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_HIGH);
            let v = rtcSetNewGeometryBuffer(
                geometry,
                RTC_BUFFER_TYPE_VERTEX,
                0,
                RTC_FORMAT_FLOAT3,
                12,
                positions.len(),
            ) as *mut f32;
            let i =
                rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, count) as *mut u32;
            if v.is_null() || i.is_null() {
                rtcReleaseGeometry(geometry);
                check("allocating the mesh buffers")?;
                return Err(EmbreeError::Call {
                    what: "allocating the mesh buffers",
                    code: -1,
                });
            }
            let verts = std::slice::from_raw_parts_mut(v, positions.len() * 3);
            for (dst, p) in verts.chunks_exact_mut(3).zip(positions) {
                dst.copy_from_slice(&p.to_array());
            }
            let index = std::slice::from_raw_parts_mut(i, count * 3);
            for (dst, t) in index.chunks_exact_mut(3).zip(triangles) {
                dst.copy_from_slice(&t);
            }
            rtcCommitGeometry(geometry);
            rtcAttachGeometry(e.scene, geometry);
            rtcReleaseGeometry(geometry);
            check("attaching the mesh")?;
            rtcCommitScene(e.scene);
            check("building the BVH")?;
        }
        Ok(e)
    }

    /// The nearest hit in `(0, ray.t_max]`: parameter and triangle index.
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, u32)> {
        self.nearest_from(ray, 0.0).map(|h| (h.t, h.tri))
    }

    /// The ray as Embree takes it, from `t_near` on.
    fn ray_hit(ray: &Ray, t_near: f32) -> RayHit1 {
        RayHit1 {
            org: ray.origin.to_array(),
            tnear: t_near,
            dir: ray.dir.to_array(),
            tfar: ray.t_max,
            mask: u32::MAX,
            geom_id: RTC_INVALID_GEOMETRY_ID,
            inst_id: [RTC_INVALID_GEOMETRY_ID],
            ..RayHit1::default()
        }
    }

    /// Whether anything lies within `[0, ray.t_max]` (Embree's any-hit query).
    fn anything(&self, ray: &Ray) -> bool {
        let mut rh = Embree::ray_hit(ray, 0.0);
        let mut context = IntersectContext::new(false);
        // SAFETY: a committed scene, an initialized context and ray; Embree
        // reads and writes only the ray's leading `RTCRay` fields.
        unsafe { rtcOccluded1(self.scene, &mut context, &mut rh) };
        // Embree marks an occluded ray with a far end of minus infinity.
        rh.tfar == f32::NEG_INFINITY
    }

    /// The nearest hit in `[t_near, ray.t_max]`, with its barycentrics.
    fn nearest_from(&self, ray: &Ray, t_near: f32) -> Option<Hit> {
        let mut rh = Embree::ray_hit(ray, t_near);
        let mut context = IntersectContext::new(false);
        // SAFETY: a committed scene, an initialized context and ray.
        unsafe { rtcIntersect1(self.scene, &mut context, &mut rh) };
        (rh.geom_id != RTC_INVALID_GEOMETRY_ID).then_some(Hit {
            t: rh.tfar,
            tri: rh.prim_id,
            u: rh.u,
            v: rh.v,
        })
    }

    /// The nearest hits of up to eight rays traced as one packet.
    pub fn intersect8(&self, rays: &[Ray]) -> [Option<(f32, u32)>; 8] {
        let mut rh = RayHit8::default();
        let mut valid = Valid8([0; 8]);
        for (k, r) in rays.iter().take(8).enumerate() {
            valid.0[k] = -1;
            [rh.org_x[k], rh.org_y[k], rh.org_z[k]] = r.origin.to_array();
            [rh.dir_x[k], rh.dir_y[k], rh.dir_z[k]] = r.dir.to_array();
            rh.tfar[k] = r.t_max;
            rh.mask[k] = u32::MAX;
        }
        rh.geom_id = [RTC_INVALID_GEOMETRY_ID; 8];
        rh.inst_id = [RTC_INVALID_GEOMETRY_ID; 8];
        let mut context = IntersectContext::new(true);
        // SAFETY: a committed scene, an initialized context, eight lanes with
        // the unused ones masked off, mask and rays 32-byte aligned.
        unsafe { rtcIntersect8(valid.0.as_ptr(), self.scene, &mut context, &mut rh) };
        std::array::from_fn(|k| {
            (valid.0[k] != 0 && rh.geom_id[k] != RTC_INVALID_GEOMETRY_ID).then_some((rh.tfar[k], rh.prim_id[k]))
        })
    }
}

/// Embree standing in for the path tracer's own hierarchy
/// ([`Tracer::with_caster`](crate::Tracer::with_caster)): single
/// rays only, as the tracer casts them.
impl RayCaster for Embree {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.nearest_from(ray, 0.0)
    }

    /// Embree's any-hit query first (most shadow rays reach their light);
    /// where something is in the way, nearest hit after nearest hit, each
    /// search starting just past the last, until one blocks or none is left
    /// before `ray.t_max`: Embree offers a filter for this only as a
    /// callback, and shadow rays through the room's window panes meet one or
    /// two hits that do not block.
    fn occluded_by(&self, ray: &Ray, blocks: &mut dyn FnMut(u32) -> bool) -> bool {
        if !self.anything(ray) {
            return false;
        }
        let mut from = 0.0f32;
        while let Some(h) = self.nearest_from(ray, from) {
            if h.t >= ray.t_max {
                return false;
            }
            if blocks(h.tri) {
                return true;
            }
            from = h.t.next_up();
        }
        false
    }
}

impl Drop for Embree {
    fn drop(&mut self) {
        // SAFETY: handles created in `new` and released once, scene first.
        unsafe {
            if !self.scene.is_null() {
                rtcReleaseScene(self.scene);
            }
            rtcReleaseDevice(self.device);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::gen::{generate, GenParams};
    use crate::{KdTree, Rng};

    #[test]
    fn embree_finds_the_triangles_our_tree_finds() {
        let scene = generate("bunny", &GenParams::default()).unwrap();
        let tree = KdTree::build(&scene, &Default::default());
        let e = Embree::new(&scene.positions, scene.triangles.iter().map(|t| t.v)).unwrap();
        let mut rng = Rng::new(3, 0);
        let rays: Vec<Ray> = (0..4096)
            .map(|_| {
                let (a, b) = rng.f32x2();
                let (c, d) = rng.f32x2();
                let o = Vec3::new(2.0, 1.35, 1.0);
                let target = Vec3::new(4.0 * a - 2.0, 4.0 * b + 2.0, 2.0 * c - 0.5 + d * 0.1);
                Ray::new(o, (target - o).normalize())
            })
            .collect();
        let mut same = 0;
        let mut hits = 0;
        for chunk in rays.chunks(8) {
            let packet = e.intersect8(chunk);
            for (k, r) in chunk.iter().enumerate() {
                let ours = tree.intersect(r).map(|h| h.tri);
                let single = e.intersect(r).map(|h| h.1);
                assert_eq!(single, packet[k].map(|h| h.1), "Embree's packet and single rays differ");
                hits += usize::from(ours.is_some());
                same += usize::from(ours == single);
            }
        }
        // Ties on shared edges may pick either triangle; nothing more.
        assert!(hits > 1000, "{hits} hits");
        assert!(same * 1000 >= rays.len() * 998, "{same} of {} rays agree", rays.len());
    }

    /// As a ray caster for the path tracer: nearest hits with their
    /// barycentrics, and shadow rays that look past triangles a filter lets
    /// through (here every other triangle), agree with our wide BVH's but
    /// for ties on shared edges.
    #[test]
    fn embree_casts_rays_as_the_tracer_needs() {
        use crate::accel::WideBvh;
        let scene = generate("room", &GenParams::default()).unwrap();
        let bvh = WideBvh::build(&scene).unwrap();
        let e = Embree::new(&scene.positions, scene.triangles.iter().map(|t| t.v)).unwrap();
        let mut rng = Rng::new(5, 0);
        let (mut rays, mut same_hit, mut same_shadow, mut blocked, mut looked_past) = (0, 0, 0, 0, 0);
        for _ in 0..4000 {
            let (a, b) = rng.f32x2();
            let (c, d) = rng.f32x2();
            let o = Vec3::new(0.5 + 3.0 * a, 0.5 + 3.0 * b, 0.3 + 2.0 * c);
            let to = Vec3::new(4.0 * d, 4.0 * a, 2.5 * b);
            if (to - o).length() < 1e-3 {
                continue;
            }
            let ray = Ray {
                t_max: (to - o).length(),
                ..Ray::new(o, (to - o).normalize())
            };
            rays += 1;
            let (ours, theirs) = (bvh.intersect(&ray), RayCaster::intersect(&e, &ray));
            if let (Some(x), Some(y)) = (ours, theirs) {
                assert!((x.t - y.t).abs() <= 1e-4 * x.t, "{x:?} {y:?}");
                if x.tri == y.tri {
                    assert!((x.u - y.u).abs() < 1e-3 && (x.v - y.v).abs() < 1e-3, "{x:?} {y:?}");
                }
            }
            same_hit += usize::from(ours.map(|h| h.tri) == theirs.map(|h| h.tri));
            let mut passed = 0;
            let mut every_other = |t: u32| {
                passed += 1;
                t.is_multiple_of(2)
            };
            let theirs = e.occluded_by(&ray, &mut every_other);
            looked_past += usize::from(passed > 1 || (passed == 1 && !theirs));
            let ours = bvh.occluded_by(&ray, |t| t.is_multiple_of(2));
            blocked += usize::from(ours);
            same_shadow += usize::from(ours == theirs);
        }
        assert!(
            blocked > 200 && looked_past > 200,
            "{blocked} blocked, {looked_past} looked past a triangle"
        );
        assert!(same_hit * 1000 >= rays * 998, "{same_hit} of {rays} nearest hits agree");
        assert!(
            same_shadow * 1000 >= rays * 998,
            "{same_shadow} of {rays} shadow rays agree"
        );
    }
}
