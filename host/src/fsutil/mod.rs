//! Writing results atomically: a temp file in the same folder, then a rename, so a reader
//! never sees a partial or corrupted output file; and reading text inputs with errors that
//! say where they are not text.
//!
//! The parts: `output_set` (an [`OutputSet`]: files staged beside their targets, then
//! committed all together or removed), `locks` (the folder locks a commit holds), `staged`
//! (what the live sets have on disk, removed on an interrupt), `paths` (which file a path
//! names, by any spelling), `read` (reading inputs) and `folders` (making output folders,
//! refusing those that cannot hold an output, clearing dead runs' temp files).

mod folders;
mod locks;
mod output_set;
mod paths;
mod read;
mod staged;

pub use folders::create_dir;
pub use output_set::{write_atomic, OutputSet};
pub use paths::{given_twice, same_file};
pub use read::{not_a_file, read_bytes, read_text};
pub use staged::{remove_staged_files_on_interrupt, INTERRUPTED_EXIT_CODE};
