//! The token ring (being written).
