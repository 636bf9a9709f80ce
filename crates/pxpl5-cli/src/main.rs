//! The `pxpl5` command line (being written).
fn main() {}
