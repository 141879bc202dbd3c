//! End-to-end tests of real holodeck processes live in `tests/`; this library is empty.
