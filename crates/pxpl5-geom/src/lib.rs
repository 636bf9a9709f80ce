//! Geometry shared by the programs and the tools, on [`glam`]'s `DVec3` (f64): what glam lacks
//! and the programs would otherwise each write again.
//!
//! - [`plane`]: the best-fit plane of a polygon (Newell's method) and a polygon's size;
//! - [`convex`]: whether a planar polygon is convex, corner by corner;
//! - [`polygon`]: what is wrong with a polygon that should be planar and convex, with the
//!   tolerances the scene files and `pxpl5 formfactor` share;
//! - [`clip`]: one Sutherland-Hodgman clipper for convex polygons;
//! - [`grid`]: the pixel grid of a view (pixel index <-> the square [-1, 1]);
//! - [`rng`]: one seeded generator, so random inputs are the same on every host.
//!
//! **Rounding.** Results must be bit-identical to the code this crate replaced, so the order of
//! operations is part of each function's contract: glam's `dot` is `x x' + y y' + z z'` (left to
//! right), `cross` the textbook formula, `normalize` multiplies by `1 / length`. Where a caller
//! needs a different order (dividing by the length), it says so at the call.

pub mod clip;
pub mod convex;
pub mod grid;
pub mod plane;
pub mod polygon;
pub mod rng;

pub use glam::DVec3;

/// A `DVec3` from the tuples the RON file formats use.
pub fn vec3((x, y, z): (f64, f64, f64)) -> DVec3 {
    DVec3::new(x, y, z)
}
