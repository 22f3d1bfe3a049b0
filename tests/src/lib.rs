//! End-to-end tests of vademecum across processes: see `tests/`.
