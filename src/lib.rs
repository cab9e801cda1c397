//! hertz-cradle: parameter sweeps of Newton's cradles with Hertzian contacts.
//!
//! Data flow (one module each): [`scene`] (TOML → checked scene) →
//! [`sweep`] (axes → scenes in id order) → [`backend`] (cpu | gpu) →
//! [`engine`] (chain, contact law, integrator, outcomes) → [`output`] (CSV, tables, traces).

pub mod cli;
pub mod engine;
pub mod error;
pub mod output;
pub mod scene;

pub use error::InputError;
