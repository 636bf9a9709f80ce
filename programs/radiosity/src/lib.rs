//! Progressive radiosity on the simulated Pixel-Planes 5 (being written).

pub mod exact;
pub mod mesh;
pub mod program;
pub mod scenes;
pub mod shot;
pub mod views;
