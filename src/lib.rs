//! hertz-cradle: parameter sweeps of Newton's cradles with Hertzian contacts.
//!
//! **The core** (always built; no clap, axum, tokio, plotters or indicatif —
//! `cargo build --lib --no-default-features` proves it):
//! [`scene`] (TOML → checked scene) → [`sweep`] (axes → scenes in id order,
//! run through a pipeline) → [`backend`] (cpu | gpu) → [`engine`] (chain,
//! contact law, integrator, outcomes) → [`output`] (CSV, Parquet, sidecars,
//! traces, safe publication); [`request`] is the typed API over them:
//! [`SweepRequest`] and [`RunRequest`], checked from plain settings, run with
//! [`Hooks`] for progress, typed rows and cancellation, failing with a typed
//! [`Error`].
//!
//! **The front ends**, clients of the core behind cargo features (all on by
//! default): `cli` (the `cradle` command line: [`cli`] flags, [`slurm`]
//! job arrays), `progress` (an indicatif bar: `progress`), `plot`
//! (plotters: `plot`), `explore` (the axum browser explorer: `explore`).
//!
//! ```
//! use hertz_cradle::{SweepRequest, SweepSettings, Hooks};
//! let dir = std::env::temp_dir().join(format!("hc-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let toml = "[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n\
//!             [[axis]]\nparam = \"gap\"\nlinspace = [0.0, 1e-5, 4]\n";
//! let settings = SweepSettings { backend: hertz_cradle::backend::BackendChoice::Cpu, ..Default::default() };
//! let req = SweepRequest::from_toml("doc", toml, ".", dir.join("t.csv"), &settings).unwrap();
//! let s = req.run(Hooks::default()).unwrap();
//! assert_eq!((s.scenes, s.ok), (4, 4));
//! # std::fs::remove_dir_all(&dir).unwrap();
//! ```

// Numeric kernels index several parallel arrays by the same body or contact.
#![allow(clippy::needless_range_loop)]

// The core.
pub mod backend;
pub mod choice;
pub mod engine;
pub mod error;
pub mod model;
pub mod optimize;
pub mod output;
pub mod request;
pub mod scene;
pub mod sweep;

// The front ends.
#[cfg(feature = "cli")]
pub mod cli;
#[cfg(feature = "explore")]
pub mod explore;
#[cfg(feature = "plot")]
pub mod plot;
#[cfg(feature = "progress")]
pub mod progress;
#[cfg(feature = "cli")]
pub mod slurm;

pub use error::InputError;
pub use request::{
    Error, Hooks, RunRequest, RunSettings, SolverSettings, SweepRequest, SweepSettings,
};
pub use sweep::session::{Progress, Summary, SweepRow};
