#![doc = include_str!("../README.md")]
//!
//! # A tour
//!
//! - [`cell`]: [`LatestCell`](cell::LatestCell), a wait-free triple buffer whose reads say
//!   [`Fresh::New`](cell::Fresh), `Old` or `NoData`; [`Stamped`](cell::Stamped) values.
//! - [`events`]: [`EventCell`](events::EventCell), safety events raised by one thread (a
//!   communication thread that lost its link) and taken by the control loop, one atomic word.
//! - [`ring`]: [`Ring`](ring::Ring), a wait-free SPSC ring that counts what it drops when full.
//! - [`stats`]: [`LatencyHistogram`](stats::LatencyHistogram) (fixed buckets, percentiles) and
//!   [`DurationStats`](stats::DurationStats).
//! - [`clock`] and [`sim`]: time sources, and a runner that steps periodic loops in timestamp order
//!   on a simulated clock, deterministically.
//! - [`stop`]: [`StopLatch`](stop::StopLatch), an e-stop request any thread raises without a
//!   lock or a queue, latched by the control loop on its next tick.
//! - [`safety`]: the always-on safety state machine (watchdog, limits, e-stop latch).
//! - [`controller`]: control laws ([`JointPid`](controller::JointPid)) and
//!   [`ControllerSet`](controller::ControllerSet).
//! - [`comm`] and [`control`]: the two loops of each robot — communication (`T_com`, trajectory
//!   to reference cell) and control (`T_ctrl`, board, safety, controller, telemetry).
//! - [`telemetry`]: the `Copy` sample the control loop reports each tick.
//! - [`exec`] (feature `std`, Linux): the periodic SCHED_FIFO executor.
//!
//! Everything but [`exec`] and the `Arc` constructors is `no_std` without `alloc`.
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]

pub(crate) mod sync;

pub mod cell;
pub mod clock;
pub mod comm;
pub mod control;
pub mod controller;
pub mod events;
pub mod ring;
pub mod safety;
pub mod sim;
pub mod stats;
pub mod stop;
pub mod telemetry;
pub mod teleop;
pub mod trajectory;

#[cfg(all(feature = "std", not(loom)))]
pub mod exec;
#[cfg(all(feature = "std", not(loom)))]
pub mod wake;
