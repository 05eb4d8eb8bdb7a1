//! What the renderer's GPU tests share: the adapter and the camera over the test cube.

use engine::gpu::Gpu;
use glam::DVec3;
use occlusion::camera::{Camera, Projection};

pub fn gpu() -> Gpu {
    Gpu::new().expect("a GPU adapter (CI installs mesa-vulkan-drivers for lavapipe)")
}

/// Looking down -z at [-12, 12]^3: orthographic (24 units tall) or perspective (30 degrees).
pub fn top_camera(perspective: bool) -> Camera {
    let bounds = [DVec3::splat(-12.0), DVec3::splat(12.0)];
    let projection = if perspective {
        Projection::Perspective { fov_y_deg: 30.0 }
    } else {
        Projection::Orthographic { height: 24.0 }
    };
    let eye = DVec3::new(0.0, 0.0, if perspective { 46.0 } else { 40.0 });
    Camera::look_at(eye, DVec3::ZERO, DVec3::Y, projection, bounds).unwrap()
}
