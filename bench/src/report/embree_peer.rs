//! Intel Embree 3 as a peer in section 1 (feature `embree`, needs libembree-dev): memory of a
//! scene built with the default flags or `RTC_SCENE_FLAG_COMPACT`, and its speed on the report's
//! rays with single-ray queries ([`Embree`]).
//!
//! Memory is counted by Embree itself: a device memory monitor callback adds every allocation
//! and subtracts every release, so the figure is exact where process RSS growth would include
//! thread stacks and allocator slack. The monitor is installed before the geometry's buffers
//! exist, so the count after filling them is the buffers and the growth during commit is the
//! BVH (build temporaries are released by then).

use std::ffi::c_void;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Instant;

use embree::{sys, Device, Scene, SceneFlags};

use super::memory_parts::MemoryParts;
use super::speed::{self, Speed};
use super::Sizes;
use crate::workload::engines::{triangle_geometry, Embree};
use crate::workload::RaySet;
use reducem::mesh::Mesh;

/// Bytes per vertex of the `embree` crate's vertex buffer (four f32, the fourth unused).
const EMBREE_VERTEX_BYTES: u64 = 16;

/// One Embree configuration as measured.
pub struct Measured {
    pub name: &'static str,
    pub parts: MemoryParts,
    pub build_seconds: f64,
    pub speed: Speed,
}

/// Builds the scene over `mesh` and traces `rays` with it.
pub fn measure(mesh: &Mesh, rays: &RaySet, sizes: &Sizes, compact: bool) -> Measured {
    // Declared first so that it outlives the device that reports into it.
    let allocated = Box::new(AtomicI64::new(0));
    let device = Device::new();
    let mut scene = Scene::new(&device);
    // SAFETY: the scene handle is valid while `scene` lives; the device reference taken by
    // rtcGetSceneDevice is released at once; `allocated` outlives the device.
    unsafe {
        let device_handle = sys::rtcGetSceneDevice(scene.handle());
        sys::rtcSetDeviceMemoryMonitorFunction(
            device_handle,
            Some(count_allocation),
            &*allocated as *const AtomicI64 as *mut c_void,
        );
        sys::rtcReleaseDevice(device_handle);
        if compact {
            sys::rtcSetSceneFlags(scene.handle(), SceneFlags::COMPACT);
        }
    }
    scene.attach_geometry(triangle_geometry(&device, mesh));
    let buffers = allocated.load(Ordering::Relaxed).max(0) as u64;
    let started = Instant::now();
    let committed = Embree(scene.commit());
    let build_seconds = started.elapsed().as_secs_f64();
    let total = allocated.load(Ordering::Relaxed).max(0) as u64;
    let vertices = (EMBREE_VERTEX_BYTES * mesh.positions.len() as u64).min(buffers);
    Measured {
        name: if compact {
            "Embree 3, compact"
        } else {
            "Embree 3, default"
        },
        parts: MemoryParts {
            vertices,
            triangles: buffers - vertices,
            hierarchy: total.saturating_sub(buffers),
            other: 0,
        },
        build_seconds,
        speed: speed::measure(&committed, rays, sizes.runs, sizes.min_trace_seconds),
    }
}

/// Embree's memory monitor: `bytes` is positive for allocations, negative for releases.
unsafe extern "C" fn count_allocation(
    counter: *mut c_void,
    bytes: sys::ssize_t,
    _post: bool,
) -> bool {
    // SAFETY: `counter` is the AtomicI64 installed by `measure`, alive while the device is.
    let counter = unsafe { &*(counter as *const AtomicI64) };
    counter.fetch_add(bytes as i64, Ordering::Relaxed);
    true
}
