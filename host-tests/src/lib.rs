//! Paper reproductions (placeholder).
