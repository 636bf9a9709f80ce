//! Progressive radiosity on the simulated Pixel-Planes 5: the scene format ([`scene`]), scenes and
//! meshing ([`scenes`],
//! [`mesh`]), exact point-to-polygon form factors ([`exact`]), the hemisphere and hemicube views
//! as GP code ([`views`]), one shot's form factors on the machine ([`shot`]), the programs the
//! machine runs ([`program`]), and host reference solutions ([`solver`]).

pub mod exact;
pub mod mesh;
pub mod program;
pub mod scene;
pub mod scenes;
pub mod shot;
pub mod solver;
pub mod views;
