//! relume, the host side: files, threads, clocks and the command line around
//! `relume-core`. The core gets slices and seeds; everything that touches the outside world
//! lives here.
//!
//! - [`error`]: the host's error, carrying file / line / pixel context; exit codes.
//! - [`fsutil`]: atomic writes (temp file, then rename).
//! - [`scene_file`], [`obj`], [`images`], [`materials_file`]: reading (and writing) the
//!   formats of scene-format.md, validated into plain descriptions.
//! - [`assemble`]: descriptions to the core's buffers (an owned scene the core borrows);
//!   [`light_placement`]: lights hidden behind a surface that still light the room;
//!   [`repeated_triangles`]: triangles two groups share, or a group gives twice.
//! - [`parallel`]: fixed tiles, results combined in a fixed order.
//! - [`render_cmd`], [`compare`], [`bench`](mod@bench): the subcommands; [`cli`] parses arguments.
//! - [`text`]: wording shared by the messages a user reads.

pub mod assemble;
pub mod bench;
pub mod cli;
pub mod compare;
pub mod coverage;
pub mod downsample;
pub mod enclosed_views;
pub mod error;
pub mod fsutil;
pub mod images;
pub mod light_placement;
pub mod materials_file;
pub mod obj;
pub mod overlapping_faces;
pub mod panorama;
pub mod parallel;
pub mod polygon;
pub mod progress;
pub mod recover;
pub mod render_cmd;
pub mod repeated_triangles;
pub mod scene_file;
pub mod text;

pub use error::Error;
