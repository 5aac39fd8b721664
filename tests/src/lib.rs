//! Shared harness for the cross-part tests.
