//! Workspace-level system tests live in `tests/tests/`; helpers shared by them live here.
