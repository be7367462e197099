//! Where the crowd stands and how it is seen: a camera, the crowd images' grid layout and clear
//! colour, and the phase convention of a crowd playing its model's animation (the crowd sample,
//! the demo, the profiler and the tests share them).

use crate::renderer::Draw;
use glam::{Mat4, Vec3};
use rrskin::predict::Affine;
use rrskin::vk::Crowd;
use rrskin::Model;

/// A perspective camera in Vulkan clip space (y down, depth 0..1).
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    pub view_proj: Mat4,
}

impl Camera {
    /// Looking from `eye` at `target` (y up), vertical field of view in radians.
    pub fn looking_at(
        eye: Vec3,
        target: Vec3,
        fov_y: f32,
        aspect: f32,
        near: f32,
        far: f32,
    ) -> Camera {
        // View: right-handed, looking down −z.
        let f = (target - eye).normalize();
        let s = f.cross(Vec3::Y).normalize();
        let u = s.cross(f);
        let view = Mat4::from_cols(
            s.extend(-s.dot(eye)),
            u.extend(-u.dot(eye)),
            (-f).extend(f.dot(eye)),
            glam::Vec4::W,
        )
        .transpose();
        // Projection to Vulkan clip space: y down, depth 0 (near) .. 1 (far).
        let h = 1.0 / (0.5 * fov_y).tan();
        let proj = Mat4::from_cols(
            glam::Vec4::new(h / aspect, 0.0, 0.0, 0.0),
            glam::Vec4::new(0.0, -h, 0.0, 0.0),
            glam::Vec4::new(0.0, 0.0, far / (near - far), -1.0),
            glam::Vec4::new(0.0, 0.0, near * far / (near - far), 0.0),
        );
        Camera {
            view_proj: proj * view,
        }
    }
}

/// The clear colour of the crowd images (the crowd sample, the demo).
pub const CROWD_BACKGROUND: [f32; 3] = [0.09, 0.1, 0.12];

/// The bone transforms (C x J) of `characters` playing `model`'s animation at its frame `frame`,
/// character c 7c frames ahead, so that neighbours are out of step. Empty if the model carries
/// no animation.
pub fn phased_poses(model: &Model, characters: usize, frame: usize) -> Vec<Affine> {
    let frames: Vec<&[Affine]> = model.animation().collect();
    if frames.is_empty() {
        return Vec::new();
    }
    (0..characters)
        .flat_map(|c| frames[(frame + 7 * c) % frames.len()].iter().copied())
        .collect()
}

/// A crowd laid out in a square grid, framed by a camera: where each character stands.
pub struct GridScene {
    pub camera: Camera,
    pub offsets: Vec<[f32; 3]>,
}

/// Lays out `characters` of `model` (y up) on a square grid spaced by its rest mesh's footprint
/// and frames them from the front, above, for an image of `aspect` width / height.
pub fn grid_scene(model: &Model, characters: usize, aspect: f32) -> GridScene {
    let rest = &model.parts().rest_positions;
    let (lo, hi) = rest
        .iter()
        .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
            (
                std::array::from_fn(|i| lo[i].min(p[i])),
                std::array::from_fn(|i| hi[i].max(p[i])),
            )
        });
    let size = (hi[0] - lo[0]).max(hi[2] - lo[2]).max(1e-3) * 1.15;
    let tall = (hi[1] - lo[1]).max(1e-3);
    let side = (characters as f32).sqrt().ceil().max(1.0) as usize;
    let extent = size * (side - 1) as f32;
    let center = Vec3::new(extent * 0.5, tall * 0.4, extent * 0.5);
    let eye = center + Vec3::new(0.0, extent * 0.45 + tall * 2.0, extent * 0.85 + tall * 3.0);
    let far = 10.0 * (extent + tall * 4.0);
    GridScene {
        camera: Camera::looking_at(eye, center, 0.8, aspect, 0.05 * tall, far),
        offsets: (0..characters)
            .map(|c| [size * (c % side) as f32, 0.0, size * (c / side) as f32])
            .collect(),
    }
}

impl GridScene {
    /// Every character of `crowd` (up to the grid's size) at its place, each with its own tint.
    pub fn draws<'a>(&self, crowd: &'a Crowd) -> Vec<Draw<'a>> {
        (0..self.offsets.len().min(crowd.character_count()))
            .map(|c| Draw {
                crowd,
                character: c,
                offset: self.offsets[c],
                color: [
                    0.55 + 0.35 * ((c * 37 % 11) as f32 / 10.0),
                    0.62,
                    0.78 - 0.2 * ((c * 13 % 7) as f32 / 6.0),
                ],
            })
            .collect()
    }
}
