//! A small safe binding to Intel's Embree 3 ray-tracing kernels (the system's `libembree3`,
//! Debian's `libembree-dev` 3.13.5): one static triangle mesh, closest-hit queries for single
//! rays (`rtcIntersect1`) and for fans of rays from one origin in packets of 4, 8 or 16
//! (`rtcIntersect4/8/16`).
//!
//! It knows nothing of its users: a scene is f32 vertex positions and u32 triangle indices,
//! a hit is the distance `t` and the triangle's index (Embree's `primID`).
//!
//! # What a hit is
//! The closest hit with `tnear < t <= tfar` (Embree's own interval test, made in scaled form:
//! `|den| tnear < T <= |den| tfar`), edges and corners included, both faces. Where several
//! triangles are hit at the same `t` Embree keeps whichever its traversal met last; this
//! crate installs an intersection filter (Embree's `rtcSetGeometryIntersectFilterFunction`)
//! that keeps the smallest triangle index instead, so the answer does not depend on the
//! hierarchy Embree built or on the packet width.
//!
//! # Determinism
//! The device is made with a fixed number of build threads (one by default), so the build
//! does not depend on the machine's core count. Embree picks its kernels for the CPU it runs
//! on (SSE4.2, AVX, AVX2, AVX-512) and divides with an approximate reciprocal refined by one
//! Newton step, so `t` may differ in the last bits between CPU families; on one machine the
//! same scene and ray give the same answer every time, from any thread.

#![allow(unsafe_code)] // FFI to libembree3: every unsafe block says why it is sound.

mod sys;

use std::ffi::{CString, c_uint};
use std::num::NonZeroU32;
use std::ptr::NonNull;

use sys::*;

/// How hard Embree works on its hierarchy (`RTCBuildQuality`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BuildQuality {
    /// Morton-code build: fastest to build, slowest to trace.
    Low,
    /// Binned SAH (Embree's default).
    Medium,
    /// Binned SAH with spatial splits: slowest to build, fastest to trace.
    #[default]
    High,
}

impl BuildQuality {
    fn raw(self) -> c_uint {
        match self {
            Self::Low => 0,
            Self::Medium => 1,
            Self::High => 2,
        }
    }
}

/// How a scene is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SceneOptions {
    pub quality: BuildQuality,
    /// Embree's `threads=` device setting: the worker threads of the build (queries run on
    /// the caller's thread whatever this is).
    pub build_threads: NonZeroU32,
}

impl Default for SceneOptions {
    fn default() -> Self {
        Self {
            quality: BuildQuality::High,
            build_threads: NonZeroU32::MIN,
        }
    }
}

/// How a fan of rays is sent to Embree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Packet {
    /// One `rtcIntersect1` per ray.
    Single,
    /// `rtcIntersect4` on groups of 4 rays.
    X4,
    /// `rtcIntersect8` on groups of 8 rays.
    X8,
    /// `rtcIntersect16` on groups of 16 rays.
    X16,
}

/// The closest intersection along a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit: origin + t * dir.
    pub t: f32,
    /// Index of the triangle in the slice the scene was built from.
    pub prim: u32,
}

#[derive(Debug, thiserror::Error)]
pub enum EmbreeError {
    #[error("rtcNewDevice(\"{config}\") failed: Embree error {code} ({})", error_name(*code))]
    Device { config: String, code: u32 },
    #[error("{call} failed: Embree error {code} ({})", error_name(*code))]
    Call { call: &'static str, code: u32 },
    #[error("triangle {triangle} uses vertex {vertex}, but there are {vertices} vertices")]
    IndexOutOfRange {
        triangle: usize,
        vertex: u32,
        vertices: usize,
    },
    #[error("{0} triangles: Embree numbers triangles with 32 bits")]
    TooManyTriangles(usize),
    #[error("this libembree3 cannot be used: {0}")]
    Unsupported(String),
}

fn error_name(code: u32) -> &'static str {
    match code {
        0 => "none",
        1 => "unknown",
        2 => "invalid argument",
        3 => "invalid operation",
        4 => "out of memory",
        5 => "unsupported CPU",
        6 => "cancelled",
        _ => "not an Embree error code",
    }
}

/// An Embree device, released on drop.
struct Device(NonNull<RTCDeviceTy>);

impl Device {
    fn new(config: &str) -> Result<Self, EmbreeError> {
        let c = CString::new(config).expect("device config has no NUL");
        // SAFETY: `c` is a NUL-terminated string that outlives the call; Embree copies what it
        // needs from it.
        let raw = unsafe { rtcNewDevice(c.as_ptr()) };
        NonNull::new(raw)
            .map(Self)
            .ok_or_else(|| EmbreeError::Device {
                config: config.to_owned(),
                // SAFETY: a null device asks for the error of the failed device creation.
                code: unsafe { rtcGetDeviceError(std::ptr::null_mut()) },
            })
    }

    fn property(&self, prop: c_uint) -> isize {
        // SAFETY: the device is alive; reading a property has no other precondition.
        unsafe { rtcGetDeviceProperty(self.0.as_ptr(), prop) }
    }

    /// The error Embree recorded for this device on this thread since the last check.
    fn check(&self, call: &'static str) -> Result<(), EmbreeError> {
        // SAFETY: the device is alive.
        let code = unsafe { rtcGetDeviceError(self.0.as_ptr()) };
        if code == RTC_ERROR_NONE {
            Ok(())
        } else {
            Err(EmbreeError::Call { call, code })
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: we own one reference to the device and give it back once.
        unsafe { rtcReleaseDevice(self.0.as_ptr()) }
    }
}

/// A scene handle, released on drop.
struct SceneHandle(NonNull<RTCSceneTy>);

impl Drop for SceneHandle {
    fn drop(&mut self) {
        // SAFETY: we own one reference to the scene and give it back once.
        unsafe { rtcReleaseScene(self.0.as_ptr()) }
    }
}

/// A geometry handle, released on drop (the scene keeps its own reference once attached).
struct GeometryHandle(NonNull<RTCGeometryTy>);

impl Drop for GeometryHandle {
    fn drop(&mut self) {
        // SAFETY: we own one reference to the geometry and give it back once.
        unsafe { rtcReleaseGeometry(self.0.as_ptr()) }
    }
}

/// Most lanes one query carries (`rtcIntersect16`).
const MAX_LANES: usize = 16;

/// The context handed to `rtcIntersect*`: Embree passes this same pointer to the filter, so
/// the best hit so far of each ray (lane = the ray's `id`) rides behind the
/// `RTCIntersectContext`, which must come first.
#[repr(C)]
struct TieContext {
    ctx: RTCIntersectContext,
    best_t: [f32; MAX_LANES],
    best_prim: [u32; MAX_LANES],
}

impl TieContext {
    fn new() -> Self {
        Self {
            ctx: RTCIntersectContext::new(),
            best_t: [f32::INFINITY; MAX_LANES],
            best_prim: [u32::MAX; MAX_LANES],
        }
    }
}

/// Intersection filter: accepts a candidate hit only if it is closer than the best so far, or
/// as close with a smaller triangle index. Embree calls it with `tfar` already set to the
/// candidate's `t` and restores the old `tfar` for rejected lanes.
///
/// # Safety
/// Called by Embree only, during an `rtcIntersect*` of a [`Scene`], whose context is a
/// [`TieContext`] and whose rays carry their lane (< [`MAX_LANES`]) in `id`.
unsafe extern "C" fn keep_smallest_index(args: *const RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes valid arguments for the duration of the call.
    let args = unsafe { &*args };
    let n = args.n as usize;
    let ctx = args.context.cast::<TieContext>();
    let ray_f = args.ray.cast::<f32>();
    let ray_u = args.ray.cast::<u32>();
    let hit_u = args.hit.cast::<u32>();
    for i in 0..n {
        // SAFETY: `valid` has `n` entries, and the ray and hit are `n`-wide structures of
        // arrays (the header's RTCRayN_*/RTCHitN_* accessors compute the same offsets).
        // `ctx` is the TieContext of the query running on this thread; nothing else touches
        // it during the call.
        unsafe {
            let valid = args.valid.add(i);
            if *valid == 0 {
                continue;
            }
            let t = *ray_f.add(RAYN_TFAR_FIELD * n + i);
            let lane = *ray_u.add(RAYN_ID_FIELD * n + i) as usize;
            let prim = *hit_u.add(HITN_PRIMID_FIELD * n + i);
            let ctx = &mut *ctx;
            let (Some(best_t), Some(best_prim)) =
                (ctx.best_t.get_mut(lane), ctx.best_prim.get_mut(lane))
            else {
                continue; // not a lane of ours: leave Embree's verdict
            };
            if t < *best_t || (t == *best_t && prim < *best_prim) {
                *best_t = t;
                *best_prim = prim;
            } else {
                *valid = 0;
            }
        }
    }
}

/// A committed Embree scene of one triangle mesh, ready for queries from any thread.
pub struct Scene {
    // Field order is drop order: the scene before the device that made it.
    scene: SceneHandle,
    /// Held only to be released after the scene.
    _device: Device,
    triangles: usize,
    options: SceneOptions,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("triangles", &self.triangles)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

// SAFETY: Embree's handles are plain heap objects not tied to the thread that made them, and
// releasing them from another thread is allowed (reference counts are atomic).
unsafe impl Send for Scene {}
// SAFETY: after `rtcCommitScene` the scene is only read: Embree documents the rtcIntersect*
// calls on a committed scene as thread-safe, and `&self` methods call nothing else (the
// per-query state lives on each caller's stack in its TieContext).
unsafe impl Sync for Scene {}

impl Scene {
    /// Builds and commits a scene of `triangles` (indices into `vertices`).
    pub fn new(
        vertices: &[[f32; 3]],
        triangles: &[[u32; 3]],
        options: SceneOptions,
    ) -> Result<Self, EmbreeError> {
        if u32::try_from(triangles.len()).is_err() {
            return Err(EmbreeError::TooManyTriangles(triangles.len()));
        }
        for (triangle, tri) in triangles.iter().enumerate() {
            if let Some(&vertex) = tri.iter().find(|&&v| v as usize >= vertices.len()) {
                return Err(EmbreeError::IndexOutOfRange {
                    triangle,
                    vertex,
                    vertices: vertices.len(),
                });
            }
        }
        let device = Device::new(&format!(
            "threads={},set_affinity=0,start_threads=0,verbose=0",
            options.build_threads
        ))?;
        if device.property(RTC_DEVICE_PROPERTY_VERSION_MAJOR) != 3
            || device.property(RTC_DEVICE_PROPERTY_VERSION_MINOR) < 13
        {
            return Err(EmbreeError::Unsupported(format!(
                "version {}.{}, the declarations are Embree 3.13's",
                device.property(RTC_DEVICE_PROPERTY_VERSION_MAJOR),
                device.property(RTC_DEVICE_PROPERTY_VERSION_MINOR)
            )));
        }
        if device.property(RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED) == 0 {
            return Err(EmbreeError::Unsupported(
                "built without filter functions, which the tie rule needs".into(),
            ));
        }
        if device.property(RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED) != 0 {
            return Err(EmbreeError::Unsupported(
                "built with back-face culling: rays would pass through triangles from behind"
                    .into(),
            ));
        }
        // SAFETY: the device is alive.
        let scene = NonNull::new(unsafe { rtcNewScene(device.0.as_ptr()) }).map(SceneHandle);
        device.check("rtcNewScene")?;
        let scene = scene.ok_or(EmbreeError::Call {
            call: "rtcNewScene",
            code: 1,
        })?;
        if !triangles.is_empty() {
            Self::attach_mesh(&device, &scene, vertices, triangles, options.quality)?;
        }
        // SAFETY: the scene is alive and ours; flags and quality are valid enum values.
        unsafe {
            rtcSetSceneFlags(scene.0.as_ptr(), RTC_SCENE_FLAG_NONE);
            rtcSetSceneBuildQuality(scene.0.as_ptr(), options.quality.raw());
            rtcCommitScene(scene.0.as_ptr());
        }
        device.check("rtcCommitScene")?;
        Ok(Self {
            scene,
            _device: device,
            triangles: triangles.len(),
            options,
        })
    }

    /// One triangle geometry with its own copy of the vertices and indices, attached to
    /// `scene` (primID = index in `triangles`).
    fn attach_mesh(
        device: &Device,
        scene: &SceneHandle,
        vertices: &[[f32; 3]],
        triangles: &[[u32; 3]],
        quality: BuildQuality,
    ) -> Result<(), EmbreeError> {
        // SAFETY: the device is alive; the type is a valid RTCGeometryType.
        let geometry =
            NonNull::new(unsafe { rtcNewGeometry(device.0.as_ptr(), RTC_GEOMETRY_TYPE_TRIANGLE) })
                .map(GeometryHandle);
        device.check("rtcNewGeometry")?;
        let geometry = geometry.ok_or(EmbreeError::Call {
            call: "rtcNewGeometry",
            code: 1,
        })?;
        let g = geometry.0.as_ptr();
        // SAFETY: the geometry is alive. Embree allocates each buffer for `item_count` items of
        // `byte_stride` bytes (padding vertex buffers for its 16-byte loads) and returns it
        // uninitialised, or null on failure; we write exactly that many items into it. Every
        // index was checked against the vertex count above.
        unsafe {
            let vbuf = rtcSetNewGeometryBuffer(
                g,
                RTC_BUFFER_TYPE_VERTEX,
                0,
                RTC_FORMAT_FLOAT3,
                size_of::<[f32; 3]>(),
                vertices.len(),
            );
            device.check("rtcSetNewGeometryBuffer(vertex)")?;
            let vbuf = NonNull::new(vbuf.cast::<[f32; 3]>()).ok_or(EmbreeError::Call {
                call: "rtcSetNewGeometryBuffer(vertex)",
                code: 4,
            })?;
            std::ptr::copy_nonoverlapping(vertices.as_ptr(), vbuf.as_ptr(), vertices.len());
            let ibuf = rtcSetNewGeometryBuffer(
                g,
                RTC_BUFFER_TYPE_INDEX,
                0,
                RTC_FORMAT_UINT3,
                size_of::<[u32; 3]>(),
                triangles.len(),
            );
            device.check("rtcSetNewGeometryBuffer(index)")?;
            let ibuf = NonNull::new(ibuf.cast::<[u32; 3]>()).ok_or(EmbreeError::Call {
                call: "rtcSetNewGeometryBuffer(index)",
                code: 4,
            })?;
            std::ptr::copy_nonoverlapping(triangles.as_ptr(), ibuf.as_ptr(), triangles.len());
            rtcSetGeometryBuildQuality(g, quality.raw());
            rtcSetGeometryIntersectFilterFunction(g, Some(keep_smallest_index));
            rtcCommitGeometry(g);
        }
        device.check("rtcCommitGeometry")?;
        // SAFETY: both handles are alive; the scene takes its own reference to the geometry,
        // so dropping `geometry` afterwards is right.
        unsafe { rtcAttachGeometry(scene.0.as_ptr(), g) };
        device.check("rtcAttachGeometry")
    }

    /// Number of triangles the scene was built from.
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// How the scene was built.
    pub fn options(&self) -> SceneOptions {
        self.options
    }

    /// Closest hit of `origin + t * dir` with `tnear < t <= tfar`, ties to the smaller
    /// triangle index (`rtcIntersect1`). An empty or NaN interval has no hit.
    pub fn intersect(&self, origin: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> Option<Hit> {
        if tnear.partial_cmp(&tfar).is_none_or(|o| o.is_gt()) {
            return None;
        }
        let mut ctx = TieContext::new();
        let mut rayhit = RTCRayHit {
            ray: RTCRay {
                org_x: origin[0],
                org_y: origin[1],
                org_z: origin[2],
                tnear,
                dir_x: dir[0],
                dir_y: dir[1],
                dir_z: dir[2],
                time: 0.0,
                tfar,
                mask: u32::MAX,
                id: 0,
                flags: 0,
            },
            hit: RTCHit {
                prim_id: RTC_INVALID_GEOMETRY_ID,
                geom_id: RTC_INVALID_GEOMETRY_ID,
                inst_id: [RTC_INVALID_GEOMETRY_ID],
                ..RTCHit::default()
            },
        };
        // SAFETY: the scene is committed and alive for `&self`; `rayhit` is a 16-byte aligned
        // RTCRayHit and `ctx` a TieContext starting with an initialised RTCIntersectContext,
        // both on this stack frame for the whole call; lane 0 is the ray's id.
        unsafe {
            rtcIntersect1(
                self.scene.0.as_ptr(),
                (&raw mut ctx).cast::<RTCIntersectContext>(),
                &raw mut rayhit,
            );
        }
        (rayhit.hit.geom_id != RTC_INVALID_GEOMETRY_ID).then_some(Hit {
            t: rayhit.ray.tfar,
            prim: rayhit.hit.prim_id,
        })
    }

    /// Closest hits of many rays from one origin: `out[i]` for `dirs[i]`, sent to Embree as
    /// `packet` says. The answers are those of [`Scene::intersect`] (Embree's packet kernels
    /// run the same triangle test), whatever the packet width.
    ///
    /// Panics if `out` is shorter than `dirs`.
    pub fn intersect_fan(
        &self,
        origin: [f32; 3],
        dirs: &[[f32; 3]],
        tnear: f32,
        tfar: f32,
        packet: Packet,
        out: &mut [Option<Hit>],
    ) {
        assert!(
            out.len() >= dirs.len(),
            "intersect_fan: `out` shorter than `dirs`"
        );
        match packet {
            Packet::Single => {
                for (slot, dir) in out.iter_mut().zip(dirs) {
                    *slot = self.intersect(origin, *dir, tnear, tfar);
                }
            }
            Packet::X4 => self.fan_in_packets::<4>(origin, dirs, tnear, tfar, out),
            Packet::X8 => self.fan_in_packets::<8>(origin, dirs, tnear, tfar, out),
            Packet::X16 => self.fan_in_packets::<16>(origin, dirs, tnear, tfar, out),
        }
    }

    fn fan_in_packets<const K: usize>(
        &self,
        origin: [f32; 3],
        dirs: &[[f32; 3]],
        tnear: f32,
        tfar: f32,
        out: &mut [Option<Hit>],
    ) {
        const { assert!(K == 4 || K == 8 || K == 16) };
        if tnear.partial_cmp(&tfar).is_none_or(|o| o.is_gt()) {
            out[..dirs.len()].fill(None);
            return;
        }
        for (dirs, out) in dirs.chunks(K).zip(out.chunks_mut(K)) {
            let mut valid = ValidMask([0; K]);
            let mut rayhit = RTCRayHitK::<K> {
                ray: RTCRayK {
                    org_x: [origin[0]; K],
                    org_y: [origin[1]; K],
                    org_z: [origin[2]; K],
                    tnear: [tnear; K],
                    dir_x: [0.0; K],
                    dir_y: [0.0; K],
                    dir_z: [1.0; K],
                    time: [0.0; K],
                    tfar: [f32::NEG_INFINITY; K],
                    mask: [u32::MAX; K],
                    id: std::array::from_fn(|lane| lane as u32),
                    flags: [0; K],
                },
                hit: RTCHitK {
                    ng_x: [0.0; K],
                    ng_y: [0.0; K],
                    ng_z: [0.0; K],
                    u: [0.0; K],
                    v: [0.0; K],
                    prim_id: [RTC_INVALID_GEOMETRY_ID; K],
                    geom_id: [RTC_INVALID_GEOMETRY_ID; K],
                    inst_id: [[RTC_INVALID_GEOMETRY_ID; K]],
                },
            };
            for (lane, d) in dirs.iter().enumerate() {
                valid.0[lane] = -1;
                rayhit.ray.dir_x[lane] = d[0];
                rayhit.ray.dir_y[lane] = d[1];
                rayhit.ray.dir_z[lane] = d[2];
                rayhit.ray.tfar[lane] = tfar;
            }
            let mut ctx = TieContext::new();
            let scene = self.scene.0.as_ptr();
            let context = (&raw mut ctx).cast::<RTCIntersectContext>();
            let mask = valid.0.as_ptr();
            // SAFETY: the scene is committed and alive for `&self`. `valid` and `rayhit` are
            // K-wide, 64-byte aligned (more than the 16/32/64 Embree requires) and fully
            // initialised, inactive lanes included; `ctx` starts with an initialised
            // RTCIntersectContext and every ray's id is its lane (< 16). All live on this stack
            // frame for the whole call. Each pointer cast is to the same type, as K is matched.
            unsafe {
                match K {
                    4 => rtcIntersect4(mask, scene, context, (&raw mut rayhit).cast()),
                    8 => rtcIntersect8(mask, scene, context, (&raw mut rayhit).cast()),
                    _ => rtcIntersect16(mask, scene, context, (&raw mut rayhit).cast()),
                }
            }
            for (lane, slot) in out.iter_mut().enumerate().take(dirs.len()) {
                *slot = (rayhit.hit.geom_id[lane] != RTC_INVALID_GEOMETRY_ID).then_some(Hit {
                    t: rayhit.ray.tfar[lane],
                    prim: rayhit.hit.prim_id[lane],
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two unit squares (four triangles) facing +z at z = 1 and z = 2, and a copy of the
    /// first square's triangles at the same place (indices 4, 5), for ties.
    fn scene() -> Scene {
        let v = vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
            [0.0, 0.0, 2.0],
            [1.0, 0.0, 2.0],
            [1.0, 1.0, 2.0],
            [0.0, 1.0, 2.0],
        ];
        // Far square first so a traversal in index order would meet it before the near one.
        let t = [
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 2],
            [0, 2, 3],
            [2, 1, 0],
            [3, 2, 0],
        ];
        Scene::new(&v, &t, SceneOptions::default()).expect("scene builds")
    }

    #[test]
    fn closest_hit_and_tie_to_smaller_index() {
        let s = scene();
        // Through the first triangle of the near square (x > y half): triangles 2 and 4 are the
        // same triangle, so equally close: the smaller index wins.
        let h = s
            .intersect([0.7, 0.2, 0.0], [0.0, 0.0, 1.0], 0.0, 10.0)
            .expect("hit");
        assert_eq!(h.prim, 2);
        // Embree divides with a refined approximate reciprocal: t within a few ulps.
        assert!((h.t - 1.0).abs() <= 4.0 * f32::EPSILON, "t = {}", h.t);
        // The other half: triangles 3 and 5.
        let h = s
            .intersect([0.2, 0.7, 0.0], [0.0, 0.0, 1.0], 0.0, 10.0)
            .expect("hit");
        assert_eq!(h.prim, 3);
        // From between the squares upwards: the far square only.
        let h = s
            .intersect([0.7, 0.2, 1.5], [0.0, 0.0, 1.0], 0.0, 10.0)
            .expect("hit");
        assert_eq!(h.prim, 0);
        assert!((h.t - 0.5).abs() <= 2.0 * f32::EPSILON, "t = {}", h.t);
        // Interval: tfar short of the near square misses, tnear past it finds the far one.
        assert_eq!(
            s.intersect([0.7, 0.2, 0.0], [0.0, 0.0, 1.0], 0.0, 0.9),
            None
        );
        let h = s
            .intersect([0.7, 0.2, 0.0], [0.0, 0.0, 1.0], 1.5, 10.0)
            .expect("hit");
        assert_eq!(h.prim, 0);
        assert!((h.t - 2.0).abs() <= 8.0 * f32::EPSILON, "t = {}", h.t);
        // Outside the squares and an empty interval.
        assert_eq!(
            s.intersect([3.0, 3.0, 0.0], [0.0, 0.0, 1.0], 0.0, 10.0),
            None
        );
        assert_eq!(
            s.intersect([0.7, 0.2, 0.0], [0.0, 0.0, 1.0], 5.0, 1.0),
            None
        );
    }

    #[test]
    fn packets_agree_with_single_rays() {
        let s = scene();
        let origin = [0.5, 0.5, -1.0];
        let dirs: Vec<[f32; 3]> = (0..37)
            .map(|i| {
                let (a, f) = (i as f32 * 0.9, (i % 7) as f32 / 6.0);
                let d = [0.5 * f * a.cos(), 0.5 * f * a.sin(), 1.0];
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                [d[0] / n, d[1] / n, d[2] / n]
            })
            .collect();
        let mut single = vec![None; dirs.len()];
        s.intersect_fan(origin, &dirs, 0.0, 100.0, Packet::Single, &mut single);
        assert!(single.iter().filter(|h| h.is_some()).count() > 10);
        assert!(single.iter().any(|h| h.is_none()));
        for packet in [Packet::X4, Packet::X8, Packet::X16] {
            let mut out = vec![Some(Hit { t: -1.0, prim: 99 }); dirs.len()];
            s.intersect_fan(origin, &dirs, 0.0, 100.0, packet, &mut out);
            assert_eq!(out, single, "{packet:?}");
        }
    }

    #[test]
    fn bad_index_and_empty_scene() {
        let err = Scene::new(&[[0.0; 3]; 2], &[[0, 1, 2]], SceneOptions::default())
            .expect_err("index 2 of 2 vertices");
        assert!(matches!(
            err,
            EmbreeError::IndexOutOfRange { vertex: 2, .. }
        ));
        let empty = Scene::new(&[], &[], SceneOptions::default()).expect("empty scene builds");
        assert_eq!(empty.intersect([0.0; 3], [0.0, 0.0, 1.0], 0.0, 1e30), None);
    }
}
