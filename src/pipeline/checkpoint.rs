//! Checkpoints (placeholder while being written).
