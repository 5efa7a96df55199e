//! Per-strip implicit kd-tree encoding (paper 3.2).
