//! Progressive radiosity on the simulated Pixel-Planes 5: the scene format ([`scene`]), scenes and
//! meshing ([`scenes`], [`mesh`]), exact point-to-polygon form factors ([`exact`]), the hemisphere and hemicube views
//! as GP code ([`views`]), one shot's form factors on the machine ([`shot`]), the programs the
//! machine runs ([`program`]), host reference solutions ([`solver`]), and the Renderer command
//! stream of a few shots that the benchmarks time ([`stream`]).
//!
//! The experiment `pxpl5 radiosity` reports, usable from any Rust program: one method's run on a
//! machine config and its phase analysis ([`experiment`]), the seed's estimate ([`seed`]), the
//! methods side by side ([`comparison`]), and pictures of the solution and of item buffers
//! ([`picture`]).

pub mod accuracy;
pub mod comparison;
pub mod exact;
pub mod experiment;
pub mod mesh;
pub mod picture;
pub mod program;
pub mod scene;
pub mod scenes;
pub mod seed;
pub mod shot;
pub mod solver;
pub mod stream;
pub mod views;
