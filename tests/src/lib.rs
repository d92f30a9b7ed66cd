//! End-to-end checks across the DIPS crates; the tests live in `tests/tests/`.
