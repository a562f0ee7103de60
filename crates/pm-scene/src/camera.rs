//! The perspective camera and its eye rays.

use glam::{Vec2, Vec3};

/// A pinhole camera (glTF perspective camera).
#[derive(Clone, Debug)]
pub struct Camera {
    /// Eye position \[m\].
    pub position: Vec3,
    /// Unit viewing direction (the camera's -Z axis).
    pub forward: Vec3,
    /// Unit up vector (the camera's +Y axis).
    pub up: Vec3,
    /// Unit right vector (the camera's +X axis).
    pub right: Vec3,
    /// Vertical field of view \[rad\].
    pub yfov: f32,
    /// Width / height from the file, if it gave one.
    pub aspect: Option<f32>,
}

impl Camera {
    /// Unit direction of the ray through film position (sx, sy) in \[0,1\]^2, with
    /// (0,0) the top-left corner (row 0 is the top row) and `aspect` = width/height.
    pub fn ray_direction(&self, sx: f32, sy: f32, aspect: f32) -> Vec3 {
        self.rays(aspect).direction(sx, sy)
    }

    /// Eye-ray directions for an image of `aspect`, with the field of view's tangent
    /// computed once (for loops over many pixels).
    pub fn rays(&self, aspect: f32) -> CameraRays {
        CameraRays { forward: self.forward, right: self.right, up: self.up, tan_y: (0.5 * self.yfov).tan(), aspect }
    }

    /// Inverse of [`Camera::ray_direction`]: film position of a world point, if in front.
    pub fn project(&self, p: Vec3, aspect: f32) -> Option<Vec2> {
        let v = p - self.position;
        let z = v.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let tan_y = (0.5 * self.yfov).tan();
        let x = v.dot(self.right) / (z * tan_y * aspect);
        let y = v.dot(self.up) / (z * tan_y);
        Some(Vec2::new(0.5 * (x + 1.0), 0.5 * (1.0 - y)))
    }
}

/// Eye-ray directions of a [`Camera`] for one image (see [`Camera::rays`]).
#[derive(Clone, Copy, Debug)]
pub struct CameraRays {
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_y: f32,
    aspect: f32,
}

impl CameraRays {
    /// Unit direction through film position (sx, sy) in [0, 1]^2, y down: the same
    /// value as [`Camera::ray_direction`].
    #[inline]
    pub fn direction(&self, sx: f32, sy: f32) -> Vec3 {
        let x = (2.0 * sx - 1.0) * self.tan_y * self.aspect;
        let y = (1.0 - 2.0 * sy) * self.tan_y;
        (self.forward + self.right * x + self.up * y).normalize()
    }
}
