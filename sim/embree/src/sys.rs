//! Hand-written declarations of the part of Embree 3.13's C API (`embree3/rtcore.h`) this
//! crate uses, nothing more. Layouts follow the header as Debian's libembree-dev 3.13.5 ships
//! it, built with `RTC_MAX_INSTANCE_LEVEL_COUNT 1` and `RTC_MIN_WIDTH 0` (build.rs checks the
//! installed header says so): those two settings decide the size of `RTCHit` and of
//! `RTCIntersectContext`. The `const` assertions at the end pin every size and alignment.
//!
//! C enums are passed as `c_uint` (every value used is small and non-negative).

use std::ffi::{c_char, c_int, c_uint, c_void};
use std::marker::{PhantomData, PhantomPinned};

/// Opaque `struct RTCDeviceTy`.
#[repr(C)]
pub struct RTCDeviceTy {
    _data: [u8; 0],
    _marker: PhantomData<(*mut u8, PhantomPinned)>,
}
/// Opaque `struct RTCSceneTy`.
#[repr(C)]
pub struct RTCSceneTy {
    _data: [u8; 0],
    _marker: PhantomData<(*mut u8, PhantomPinned)>,
}
/// Opaque `struct RTCGeometryTy`.
#[repr(C)]
pub struct RTCGeometryTy {
    _data: [u8; 0],
    _marker: PhantomData<(*mut u8, PhantomPinned)>,
}
pub type RTCDevice = *mut RTCDeviceTy;
pub type RTCScene = *mut RTCSceneTy;
pub type RTCGeometry = *mut RTCGeometryTy;

/// `RTC_INVALID_GEOMETRY_ID`, also the "no hit" value of `primID` and `geomID`.
pub const RTC_INVALID_GEOMETRY_ID: c_uint = c_uint::MAX;

// enum RTCError
pub const RTC_ERROR_NONE: c_uint = 0;
// enum RTCDeviceProperty
pub const RTC_DEVICE_PROPERTY_VERSION_MAJOR: c_uint = 1;
pub const RTC_DEVICE_PROPERTY_VERSION_MINOR: c_uint = 2;
pub const RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED: c_uint = 65;
pub const RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED: c_uint = 66;
// enum RTCGeometryType
pub const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
// enum RTCBufferType
pub const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
pub const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
// enum RTCFormat
pub const RTC_FORMAT_UINT3: c_uint = 0x5003;
pub const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
// enum RTCSceneFlags
pub const RTC_SCENE_FLAG_NONE: c_uint = 0;
// enum RTCIntersectContextFlags
pub const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: c_uint = 0;

/// `struct RTCRay` (16-byte aligned).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, Default)]
pub struct RTCRay {
    pub org_x: f32,
    pub org_y: f32,
    pub org_z: f32,
    pub tnear: f32,
    pub dir_x: f32,
    pub dir_y: f32,
    pub dir_z: f32,
    pub time: f32,
    pub tfar: f32,
    pub mask: c_uint,
    pub id: c_uint,
    pub flags: c_uint,
}

/// `struct RTCHit` (16-byte aligned; one instance level).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, Default)]
pub struct RTCHit {
    pub ng_x: f32,
    pub ng_y: f32,
    pub ng_z: f32,
    pub u: f32,
    pub v: f32,
    pub prim_id: c_uint,
    pub geom_id: c_uint,
    pub inst_id: [c_uint; 1],
}

/// `struct RTCRayHit`: must be 16-byte aligned, which the field types give it.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct RTCRayHit {
    pub ray: RTCRay,
    pub hit: RTCHit,
}

/// `struct RTCRayK` for K = 4, 8, 16 (structure of arrays).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RTCRayK<const K: usize> {
    pub org_x: [f32; K],
    pub org_y: [f32; K],
    pub org_z: [f32; K],
    pub tnear: [f32; K],
    pub dir_x: [f32; K],
    pub dir_y: [f32; K],
    pub dir_z: [f32; K],
    pub time: [f32; K],
    pub tfar: [f32; K],
    pub mask: [c_uint; K],
    pub id: [c_uint; K],
    pub flags: [c_uint; K],
}

/// `struct RTCHitK` for K = 4, 8, 16 (one instance level).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RTCHitK<const K: usize> {
    pub ng_x: [f32; K],
    pub ng_y: [f32; K],
    pub ng_z: [f32; K],
    pub u: [f32; K],
    pub v: [f32; K],
    pub prim_id: [c_uint; K],
    pub geom_id: [c_uint; K],
    pub inst_id: [[c_uint; K]; 1],
}

/// `struct RTCRayHitK`. The header aligns RTCRayHit4/8/16 to 16/32/64 bytes; 64 satisfies
/// all three, and both halves are multiples of 64 bytes for K = 16 (of 32 for K = 8, of 16
/// for K = 4), so there is no padding between them, as in C.
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy)]
pub struct RTCRayHitK<const K: usize> {
    pub ray: RTCRayK<K>,
    pub hit: RTCHitK<K>,
}
pub type RTCRayHit4 = RTCRayHitK<4>;
pub type RTCRayHit8 = RTCRayHitK<8>;
pub type RTCRayHit16 = RTCRayHitK<16>;

/// The `valid` mask of `rtcIntersect4/8/16`: -1 for an active lane, 0 for an inactive one,
/// aligned like the packet (16/32/64 bytes; 64 covers all).
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy)]
pub struct ValidMask<const K: usize>(pub [c_int; K]);

/// Opaque `struct RTCRayN` / `struct RTCHitN` as a filter function sees them: K-wide
/// structures of arrays with K = `RTCFilterFunctionNArguments::n`.
#[repr(C)]
pub struct RTCRayN {
    _data: [u8; 0],
}
#[repr(C)]
pub struct RTCHitN {
    _data: [u8; 0],
}

/// `struct RTCFilterFunctionNArguments`.
#[repr(C)]
#[derive(Debug)]
pub struct RTCFilterFunctionNArguments {
    pub valid: *mut c_int,
    pub geometry_user_ptr: *mut c_void,
    pub context: *mut RTCIntersectContext,
    pub ray: *mut RTCRayN,
    pub hit: *mut RTCHitN,
    pub n: c_uint,
}

/// `RTCFilterFunctionN`; `None` is C's NULL.
pub type RTCFilterFunctionN =
    Option<unsafe extern "C" fn(args: *const RTCFilterFunctionNArguments)>;

/// `struct RTCIntersectContext` with one instance level and no minimum width.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RTCIntersectContext {
    pub flags: c_uint,
    pub filter: RTCFilterFunctionN,
    pub inst_id: [c_uint; 1],
}

impl RTCIntersectContext {
    /// What the header's inline `rtcInitIntersectContext` does: incoherent rays, no context
    /// filter, every instance level invalid.
    pub fn new() -> Self {
        Self {
            flags: RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT,
            filter: None,
            inst_id: [RTC_INVALID_GEOMETRY_ID],
        }
    }
}

/// Offsets, in 4-byte words, of the fields a filter function reads in a K-wide `RTCRayN`
/// and `RTCHitN` (the header's `RTCRayN_tfar`, `RTCRayN_id`, `RTCHitN_primID`): field
/// number times K plus the lane.
pub const RAYN_TFAR_FIELD: usize = 8;
pub const RAYN_ID_FIELD: usize = 10;
pub const HITN_PRIMID_FIELD: usize = 5;

// Linked by build.rs (`cargo::rustc-link-lib=dylib=embree3`).
unsafe extern "C" {
    pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    pub fn rtcReleaseDevice(device: RTCDevice);
    pub fn rtcGetDeviceProperty(device: RTCDevice, prop: c_uint) -> isize;
    pub fn rtcGetDeviceError(device: RTCDevice) -> c_uint;

    pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
    pub fn rtcReleaseScene(scene: RTCScene);
    pub fn rtcSetSceneBuildQuality(scene: RTCScene, quality: c_uint);
    pub fn rtcSetSceneFlags(scene: RTCScene, flags: c_uint);
    pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
    pub fn rtcCommitScene(scene: RTCScene);

    pub fn rtcNewGeometry(device: RTCDevice, kind: c_uint) -> RTCGeometry;
    pub fn rtcReleaseGeometry(geometry: RTCGeometry);
    pub fn rtcSetGeometryBuildQuality(geometry: RTCGeometry, quality: c_uint);
    pub fn rtcSetNewGeometryBuffer(
        geometry: RTCGeometry,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        byte_stride: usize,
        item_count: usize,
    ) -> *mut c_void;
    pub fn rtcSetGeometryIntersectFilterFunction(geometry: RTCGeometry, filter: RTCFilterFunctionN);
    pub fn rtcCommitGeometry(geometry: RTCGeometry);

    pub fn rtcIntersect1(
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit,
    );
    pub fn rtcIntersect4(
        valid: *const c_int,
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit4,
    );
    pub fn rtcIntersect8(
        valid: *const c_int,
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit8,
    );
    pub fn rtcIntersect16(
        valid: *const c_int,
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit16,
    );
}

// Sizes and alignments as C lays the header's structs out on x86-64 and aarch64.
const _: () = {
    use std::mem::{align_of, size_of};
    assert!(size_of::<RTCRay>() == 48 && align_of::<RTCRay>() == 16);
    assert!(size_of::<RTCHit>() == 32 && align_of::<RTCHit>() == 16);
    assert!(size_of::<RTCRayHit>() == 80 && align_of::<RTCRayHit>() == 16);
    assert!(size_of::<RTCRayHit4>() == 12 * 16 + 8 * 16);
    assert!(size_of::<RTCRayHit8>() == 12 * 32 + 8 * 32);
    assert!(size_of::<RTCRayHit16>() == 12 * 64 + 8 * 64);
    assert!(std::mem::offset_of!(RTCRayHit16, hit) == 12 * 64);
    assert!(std::mem::offset_of!(RTCRayHit8, hit) == 12 * 32);
    assert!(std::mem::offset_of!(RTCRayHit4, hit) == 12 * 16);
    assert!(std::mem::offset_of!(RTCRayK<8>, tfar) == RAYN_TFAR_FIELD * 8 * 4);
    assert!(std::mem::offset_of!(RTCRayK<8>, id) == RAYN_ID_FIELD * 8 * 4);
    assert!(std::mem::offset_of!(RTCHitK<8>, prim_id) == HITN_PRIMID_FIELD * 8 * 4);
    assert!(size_of::<RTCIntersectContext>() == 24 && align_of::<RTCIntersectContext>() == 8);
    assert!(size_of::<RTCFilterFunctionNArguments>() == 48);
};
