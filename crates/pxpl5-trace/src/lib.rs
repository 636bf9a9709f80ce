//! Trace writers (being written).
