//! The identification strategies, one file each, all behind [`crate::strategy::Strategy`].

pub mod exact;
pub mod hybrid;
pub mod least_squares;
pub mod thesis;
