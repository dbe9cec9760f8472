//! `acdf-io` is how acdf touches files and memory on a user's behalf, kept
//! out of the vocabulary crate so that the traits stay free of I/O: every
//! file acdf writes goes through [`fsio::write_atomic`] (a temporary file
//! beside the target, renamed into place, so an existing file is never left
//! half written), every input file is read through [`fsio::Input`] with a
//! bound, every allocation sized by input is checked against the memory
//! limit of [`limits`], and a program that writes files can ask for its
//! temporary files to be removed when it is interrupted
//! ([`fsio::install_interrupt_cleanup`]).

#![forbid(unsafe_code)]

pub mod fsio;
pub mod limits;
