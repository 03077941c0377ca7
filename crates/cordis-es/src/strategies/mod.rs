//! The identification strategies, one file each, all behind [`crate::strategy::Strategy`].

pub mod thesis;
