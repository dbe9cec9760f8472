//! The C entry points called from Rust as a C program would call them:
//! failures return NULL or a neutral value and leave a one-line message for
//! the calling thread alone; a batch equals the single draws; a saved
//! sampler loads for its material and is refused for another.

use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};

use acdf_capi::*;

fn last_error() -> String {
    // SAFETY: the library returns a NUL-terminated string it keeps alive.
    unsafe { CStr::from_ptr(acdf_last_error()) }
        .to_str()
        .unwrap()
        .to_string()
}

fn c(s: &str) -> CString {
    CString::new(s).unwrap()
}

#[test]
fn failures_return_null_and_name_their_cause() {
    unsafe {
        assert!(acdf_material_load(null()).is_null());
        assert_eq!(last_error(), "spec is NULL");
        assert!(acdf_material_load(c("builtin:bogus").as_ptr()).is_null());
        assert!(last_error().contains("bogus"), "{}", last_error());
        let m = acdf_material_load(c("builtin:nickel").as_ptr());
        assert!(!m.is_null());
        assert!(acdf_sampler_new(m, c("no-such-sampler").as_ptr()).is_null());
        assert!(
            last_error().starts_with("unknown sampler `no-such-sampler`"),
            "{}",
            last_error()
        );
        let s = acdf_sampler_new(m, c("adaptive:chi2").as_ptr());
        assert!(!s.is_null());
        let (wo, u) = ([0.0f32, 0.0, 1.0], [0.3f32, 0.7]);
        let (mut wi, mut pdf) = ([1.0f32; 3], 1.0f32);
        assert_eq!(
            acdf_sampler_sample(s, wo.as_ptr(), null(), wi.as_mut_ptr(), &mut pdf),
            0
        );
        assert_eq!((wi, pdf), ([0.0; 3], 0.0));
        assert_eq!(last_error(), "u is NULL");
        assert_eq!(acdf_sampler_pdf(null(), wo.as_ptr(), wo.as_ptr()), 0.0);
        assert_eq!(last_error(), "sampler is NULL");
        // wo below the horizon: no draw, not a failure of the call.
        let below = [0.0f32, 0.0, -1.0];
        assert_eq!(
            acdf_sampler_sample(s, below.as_ptr(), u.as_ptr(), wi.as_mut_ptr(), &mut pdf),
            0
        );
        assert_eq!(
            acdf_sampler_sample(s, wo.as_ptr(), u.as_ptr(), wi.as_mut_ptr(), &mut pdf),
            1
        );
        assert!(wi[2] > 0.0 && pdf > 0.0);
        assert!(acdf_sampler_storage_bytes(s) > 0);
        let mut rgb = [0.0f32; 3];
        acdf_material_eval(m, wo.as_ptr(), wi.as_ptr(), rgb.as_mut_ptr());
        assert!(rgb.iter().all(|v| v.is_finite() && *v > 0.0), "{rgb:?}");
        assert!(acdf_envmap_load(c("/nonexistent/sky.hdr").as_ptr()).is_null());
        assert!(
            last_error().contains("/nonexistent/sky.hdr"),
            "{}",
            last_error()
        );
        acdf_sampler_free(s);
        acdf_material_free(m);
        // Freeing NULL is allowed.
        acdf_sampler_free(null_mut());
        acdf_material_free(null_mut());
    }
}

#[test]
fn errors_belong_to_the_thread_that_failed() {
    unsafe {
        assert!(acdf_material_load(c("builtin:first-thread").as_ptr()).is_null());
    }
    let other = std::thread::spawn(|| {
        let before = last_error();
        unsafe {
            assert!(acdf_material_load(c("builtin:other-thread").as_ptr()).is_null());
        }
        (before, last_error())
    })
    .join()
    .unwrap();
    assert_eq!(other.0, "");
    assert!(other.1.contains("other-thread"));
    assert!(last_error().contains("first-thread"));
}

#[test]
fn a_batch_equals_the_single_draws() {
    unsafe {
        let m = acdf_material_load(c("builtin:gray-plastic").as_ptr());
        let s = acdf_sampler_new(m, c("outgoing:chi2").as_ptr());
        assert!(!s.is_null(), "{}", last_error());
        let wo = [0.5f32, 0.1, 0.860_232_5];
        let n = 1000;
        let u: Vec<f32> = (0..2 * n)
            .map(|k| ((k * 7919) % 1000) as f32 / 1000.0)
            .collect();
        let (mut wi, mut pdf) = (vec![0.0f32; 3 * n], vec![0.0f32; n]);
        let valid = acdf_sampler_sample_batch(
            s,
            wo.as_ptr(),
            u.as_ptr(),
            n,
            wi.as_mut_ptr(),
            pdf.as_mut_ptr(),
        );
        let mut count = 0;
        for k in 0..n {
            let (mut one, mut p) = ([0.0f32; 3], 0.0f32);
            let drawn = acdf_sampler_sample(
                s,
                wo.as_ptr(),
                u[2 * k..].as_ptr(),
                one.as_mut_ptr(),
                &mut p,
            );
            count += drawn as usize;
            // Batches may order their arithmetic differently: 1e-5.
            assert!(
                (p - pdf[k]).abs() <= 1e-5 * p.max(pdf[k]),
                "{k}: {p} vs {}",
                pdf[k]
            );
            for c in 0..3 {
                assert!((one[c] - wi[3 * k + c]).abs() <= 1e-5, "{k}");
            }
        }
        assert_eq!(valid, count);
        assert!(valid > 900);
        acdf_sampler_free(s);
        acdf_material_free(m);
    }
}

#[test]
fn a_saved_sampler_loads_for_its_material_only() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nickel.acdfs");
    let nickel = acdf::load_material(&"builtin:nickel".parse().unwrap(), None).unwrap();
    let options = acdf::SamplerOptions {
        resolution: "8x1x32x8".parse().unwrap(),
        ..acdf::SamplerOptions::default()
    };
    let built = acdf::make_sampler("adaptive:dp", &nickel, &options).unwrap();
    acdf::registry::save_sampler(&built, &path).unwrap();
    let p = c(path.to_str().unwrap());
    unsafe {
        let m = acdf_material_load(c("builtin:nickel").as_ptr());
        let s = acdf_sampler_load(m, p.as_ptr());
        assert!(!s.is_null(), "{}", last_error());
        assert_eq!(
            acdf_sampler_storage_bytes(s),
            acdf::core::BxdfSampler::storage_bytes(&built)
        );
        acdf_sampler_free(s);
        let other = acdf_material_load(c("builtin:lambert").as_ptr());
        assert!(acdf_sampler_load(other, p.as_ptr()).is_null());
        assert!(
            last_error().contains("was built for material"),
            "{}",
            last_error()
        );
        acdf_material_free(other);
        acdf_material_free(m);
    }
}

/// One sampler drawn from by four threads at once (its tables built on
/// first use, by whichever thread comes first) gives every thread the
/// draws one thread alone gets.
#[test]
fn threads_share_one_sampler() {
    struct Shared(*const AcdfSampler);
    // SAFETY: the header promises that a sampler may be read by any number
    // of threads at once.
    unsafe impl Sync for Shared {}
    unsafe impl Send for Shared {}
    unsafe {
        let m = acdf_material_load(c("builtin:nickel").as_ptr());
        let s = acdf_sampler_new(m, c("adaptive:chi2").as_ptr());
        let shared = Shared(s);
        let draws = |s: &Shared, wo: [f32; 3]| -> Vec<([f32; 3], f32)> {
            (0..2000)
                .map(|k| {
                    let u = [
                        ((k * 37) % 2000) as f32 / 2000.0,
                        (k as f32 * 0.618_034).fract(),
                    ];
                    let (mut wi, mut pdf) = ([0.0f32; 3], 0.0f32);
                    acdf_sampler_sample(s.0, wo.as_ptr(), u.as_ptr(), wi.as_mut_ptr(), &mut pdf);
                    (wi, pdf)
                })
                .collect()
        };
        let wos: Vec<[f32; 3]> = (0..4)
            .map(|t| {
                let theta = 0.3 + 0.3 * t as f32;
                [theta.sin(), 0.0, theta.cos()]
            })
            .collect();
        let together: Vec<Vec<([f32; 3], f32)>> = std::thread::scope(|scope| {
            let handles: Vec<_> = wos
                .iter()
                .map(|&wo| {
                    let shared = &shared;
                    scope.spawn(move || draws(shared, wo))
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for (wo, got) in wos.iter().zip(&together) {
            assert_eq!(got, &draws(&shared, *wo));
            assert!(got.iter().filter(|d| d.1 > 0.0).count() > 1500);
        }
        acdf_sampler_free(s);
        acdf_material_free(m);
    }
}

/// Files that are not what they are loaded as: a typed message, no handle.
#[test]
fn bad_files_are_refused_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.acdfs");
    std::fs::write(&junk, b"not a sampler file at all").unwrap();
    let bsdf = dir.path().join("cut.bsdf");
    std::fs::write(&bsdf, b"tensor_file").unwrap();
    let hdr = dir.path().join("cut.hdr");
    std::fs::write(&hdr, b"#?RADIANCE\n").unwrap();
    unsafe {
        let m = acdf_material_load(c("builtin:lambert").as_ptr());
        assert!(acdf_sampler_load(m, c(junk.to_str().unwrap()).as_ptr()).is_null());
        assert!(last_error().contains("junk.acdfs"), "{}", last_error());
        assert!(acdf_sampler_load(m, null()).is_null());
        assert_eq!(last_error(), "path is NULL");
        assert!(acdf_material_load(c(bsdf.to_str().unwrap()).as_ptr()).is_null());
        assert!(last_error().contains("cut.bsdf"), "{}", last_error());
        assert!(acdf_envmap_load(c(hdr.to_str().unwrap()).as_ptr()).is_null());
        assert!(last_error().contains("cut.hdr"), "{}", last_error());
        assert_eq!(last_error().lines().count(), 1);
        acdf_material_free(m);
    }
}
