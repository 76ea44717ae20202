//! Host simulator (placeholder).
fn main() {}
