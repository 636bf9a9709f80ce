//! scenes (being written).
