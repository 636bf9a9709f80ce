//! Progressive radiosity on the simulated Pixel-Planes 5 (being written).

pub mod exact;
pub mod mesh;
pub mod scenes;
