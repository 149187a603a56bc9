//! Closed-form Sim(3) / SE(3) alignment of corresponding point sets.
