//! What a test does when the measured data it needs is absent.
//!
//! A developer without `../shared/data` still runs the whole suite: the
//! tests that need the data print `skipping: REASON` and pass. CI always
//! has the data, so there a skip would hide a broken data path; CI sets
//! `ACDF_REQUIRE_DATA=1`, and every such skip becomes a failure.

/// Whether the environment asks that tests needing the shared data fail
/// instead of skipping: `ACDF_REQUIRE_DATA` set to anything but empty or
/// `0`.
pub fn data_required() -> bool {
    std::env::var_os("ACDF_REQUIRE_DATA").is_some_and(|v| !v.is_empty() && v != "0")
}

/// The one way a test skips for want of data: prints `skipping: REASON`,
/// or, where [`data_required`], fails the test (panics) with the reason.
pub fn skip_without_data(reason: impl std::fmt::Display) {
    assert!(
        !data_required(),
        "the shared data this test needs is absent and ACDF_REQUIRE_DATA is set: {reason}"
    );
    println!("skipping: {reason}");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_required_skip_fails_and_an_optional_one_passes() {
        // Both branches in one test: the variable is process-wide.
        let saved = std::env::var_os("ACDF_REQUIRE_DATA");
        std::env::set_var("ACDF_REQUIRE_DATA", "0");
        assert!(!data_required());
        skip_without_data("no data (optional)");
        std::env::set_var("ACDF_REQUIRE_DATA", "1");
        assert!(data_required());
        assert!(std::panic::catch_unwind(|| skip_without_data("no data (required)")).is_err());
        match saved {
            Some(v) => std::env::set_var("ACDF_REQUIRE_DATA", v),
            None => std::env::remove_var("ACDF_REQUIRE_DATA"),
        }
    }
}
