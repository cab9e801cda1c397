//! hertz-cradle: parameter sweeps of Newton's cradles with Hertzian contacts.
//!
//! Data flow (one module each): [`scene`] (TOML → checked scene) →
//! [`sweep`] (axes → scenes in id order) → [`backend`] (cpu | gpu) →
//! [`engine`] (chain, contact law, integrator, outcomes) → [`output`] (CSV, tables, traces).

// Numeric kernels index several parallel arrays by the same body or contact.
#![allow(clippy::needless_range_loop)]

pub mod backend;
pub mod cli;
pub mod config;
pub mod engine;
pub mod error;
pub mod explore;
pub mod output;
pub mod plot;
pub mod scene;
pub mod slurm;
pub mod sweep;

pub use error::InputError;
