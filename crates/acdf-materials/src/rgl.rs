//! placeholder: RGL tensor files (issue 9).
