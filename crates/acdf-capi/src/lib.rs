//! `acdf-capi` puts acdf's samplers behind a C interface, so that a C or
//! C++ renderer can load a measured material, build or load a sampler, and
//! draw and evaluate directions without Rust on its side: a shared and a
//! static library (`libacdf_capi.so`, `libacdf_capi.a`) and the header
//! `include/acdf.h`, generated from this file by cbindgen.
//!
//! The conventions are those of the rest of acdf and are stated in the
//! header: directions in the local shading frame (z along the normal, wo
//! and wi pointing away from the surface) for BRDFs and in the map's frame
//! for environment maps, densities per unit solid angle. Every object is an
//! opaque handle with a create and a free function; every entry point
//! catches panics, so none crosses into C; a failure returns NULL (or a
//! neutral value) and leaves its message, worded as the `acdf` command
//! words it, for [`acdf_last_error`] in the calling thread.

use std::cell::RefCell;
use std::ffi::{c_char, c_int, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::Arc;

use acdf::env_registry::{make_env_sampler, AnyEnvSampler, EnvSamplerOptions};
use acdf::registry::{load_sampler_for, make_sampler, AnySampler, SamplerOptions};
use acdf::{Material, MaterialSpec};
use acdf_core::{Brdf, BxdfSample, BxdfSampler, SphereSampler, Vec2, Vec3};
use acdf_lights::EnvMap;

/// A measured or analytic material: its BRDF f_r.
pub struct AcdfMaterial {
    material: Material,
}

/// A BRDF sampler for one material.
pub struct AcdfSampler {
    sampler: AnySampler,
}

/// An environment map (a lat-long HDR image).
pub struct AcdfEnvMap {
    map: Arc<EnvMap>,
}

/// A sampler of directions towards an environment map.
pub struct AcdfEnvSampler {
    sampler: AnyEnvSampler,
}

thread_local! {
    /// The calling thread's last failure.
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// Keep `message`, on one line ([`acdf::error::one_line`], which also
/// escapes NUL bytes), as the thread's last failure.
fn set_error(message: &str) {
    let text = CString::new(acdf::error::one_line(message)).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// Run `f`, turning an error or a panic into `fallback` and the thread's
/// last failure.
fn guarded<T>(fallback: T, f: impl FnOnce() -> Result<T, String>) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(value)) => value,
        Ok(Err(message)) => {
            set_error(&message);
            fallback
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            set_error(&format!("internal error: {what}"));
            fallback
        }
    }
}

/// The UTF-8 string behind `p`, or an error naming `what`.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string.
unsafe fn text<'a>(p: *const c_char, what: &str) -> Result<&'a str, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: the caller promises a NUL-terminated string.
    unsafe { CStr::from_ptr(p) }
        .to_str()
        .map_err(|_| format!("{what} is not UTF-8"))
}

/// The object behind a handle, or an error naming `what`.
///
/// # Safety
/// `p` is NULL or a live handle of this library.
unsafe fn object<'a, T>(p: *const T, what: &str) -> Result<&'a T, String> {
    // SAFETY: the caller promises a live handle when it is not NULL.
    unsafe { p.as_ref() }.ok_or_else(|| format!("{what} is NULL"))
}

/// `n` floats at `p`, or an error naming `what`.
///
/// # Safety
/// `p` is NULL or points to `n` readable floats.
unsafe fn floats<'a>(p: *const f32, n: usize, what: &str) -> Result<&'a [f32], String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: the caller promises `n` readable floats.
    Ok(unsafe { std::slice::from_raw_parts(p, n) })
}

/// `n` writable floats at `p`, or an error naming `what`.
///
/// # Safety
/// `p` is NULL or points to `n` writable floats.
unsafe fn floats_mut<'a>(p: *mut f32, n: usize, what: &str) -> Result<&'a mut [f32], String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: the caller promises `n` writable floats.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, n) })
}

/// Three floats at `p` as a vector.
///
/// # Safety
/// As [`floats`].
unsafe fn vec3(p: *const f32, what: &str) -> Result<Vec3, String> {
    // SAFETY: forwarded.
    let v = unsafe { floats(p, 3, what) }?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// Box `value` as a handle.
fn handle<T>(value: T) -> *mut T {
    Box::into_raw(Box::new(value))
}

/// Free a handle made by [`handle`].
///
/// # Safety
/// `p` is NULL or a handle of this library not yet freed.
unsafe fn free<T>(p: *mut T) {
    if !p.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: the caller promises a live handle made by `handle`.
            drop(unsafe { Box::from_raw(p) })
        }));
    }
}

/// The message of the calling thread's last failure ("" when none has
/// failed). The string belongs to the library and stays valid until the
/// thread's next failing call.
#[no_mangle]
pub extern "C" fn acdf_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Load a material by any spec the acdf command takes: `builtin:NAME`, a
/// MERL `.binary` or RGL `.bsdf` path, or `nbrdf:NAME` (with the default
/// Neural-BRDF weights). NULL on failure.
///
/// # Safety
/// `spec` is NULL or a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn acdf_material_load(spec: *const c_char) -> *mut AcdfMaterial {
    guarded(std::ptr::null_mut(), || {
        // SAFETY: forwarded from the caller.
        let spec: MaterialSpec = unsafe { text(spec, "spec") }?
            .parse()
            .map_err(|e: acdf::Error| e.to_string())?;
        let material = acdf::load_material(&spec, None).map_err(|e| e.to_string())?;
        Ok(handle(AcdfMaterial { material }))
    })
}

/// Free a material (NULL is ignored). Free its samplers first.
///
/// # Safety
/// `m` is NULL or a material not yet freed.
#[no_mangle]
pub unsafe extern "C" fn acdf_material_free(m: *mut AcdfMaterial) {
    // SAFETY: forwarded from the caller.
    unsafe { free(m) }
}

/// f_r(wo, wi) in 1/sr as RGB into `rgb` (3 floats); zeros on failure.
///
/// # Safety
/// `m` is a live material; `wo` and `wi` point to 3 floats, `rgb` to 3
/// writable floats.
#[no_mangle]
pub unsafe extern "C" fn acdf_material_eval(
    m: *const AcdfMaterial,
    wo: *const f32,
    wi: *const f32,
    rgb: *mut f32,
) {
    guarded((), || {
        // SAFETY: forwarded from the caller.
        let out = unsafe { floats_mut(rgb, 3, "rgb") }?;
        out.fill(0.0);
        // SAFETY: forwarded from the caller.
        let (m, wo, wi) = unsafe { (object(m, "material")?, vec3(wo, "wo")?, vec3(wi, "wi")?) };
        let f = m.material.brdf.eval(wo, wi);
        out.copy_from_slice(&f.to_array());
        Ok(())
    })
}

/// A sampler of `m` by any BRDF sampler name of the acdf command
/// (`cosine`, `uniform`, `adaptive:chi2`, `outgoing:chi2`, `rgl`, ...),
/// with the command's default options. Tabulated samplers build their
/// tables on first use. NULL on failure.
///
/// # Safety
/// `m` is a live material; `name` a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn acdf_sampler_new(
    m: *const AcdfMaterial,
    name: *const c_char,
) -> *mut AcdfSampler {
    guarded(std::ptr::null_mut(), || {
        // SAFETY: forwarded from the caller.
        let (m, name) = unsafe { (object(m, "material")?, text(name, "name")?) };
        let sampler = make_sampler(name, &m.material, &SamplerOptions::default())
            .map_err(|e| e.to_string())?;
        Ok(handle(AcdfSampler { sampler }))
    })
}

/// A sampler saved by `acdf build`, loaded from `path` and checked against
/// `m` as `--sampler-file` is (a file built for other material content is
/// refused). NULL on failure.
///
/// # Safety
/// `m` is a live material; `path` a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn acdf_sampler_load(
    m: *const AcdfMaterial,
    path: *const c_char,
) -> *mut AcdfSampler {
    guarded(std::ptr::null_mut(), || {
        // SAFETY: forwarded from the caller.
        let (m, path) = unsafe { (object(m, "material")?, text(path, "path")?) };
        let sampler = load_sampler_for(Path::new(path), &m.material).map_err(|e| e.to_string())?;
        Ok(handle(AcdfSampler { sampler }))
    })
}

/// Free a sampler (NULL is ignored).
///
/// # Safety
/// `s` is NULL or a sampler not yet freed.
#[no_mangle]
pub unsafe extern "C" fn acdf_sampler_free(s: *mut AcdfSampler) {
    // SAFETY: forwarded from the caller.
    unsafe { free(s) }
}

/// Draw wi for `wo` from the uniform pair `u`: 1 with the direction in `wi`
/// (3 floats) and its density in `pdf`; 0 when there is no draw (wo at or
/// below the horizon, a draw below it, or a failure), with `wi` and `pdf`
/// set to 0. The same numbers as `acdf sample` for the same wo and u.
///
/// # Safety
/// `s` is a live sampler; `wo` points to 3 floats and `u` to 2; `wi` to 3
/// writable floats and `pdf` to one.
#[no_mangle]
pub unsafe extern "C" fn acdf_sampler_sample(
    s: *const AcdfSampler,
    wo: *const f32,
    u: *const f32,
    wi: *mut f32,
    pdf: *mut f32,
) -> c_int {
    guarded(0, || {
        // SAFETY: forwarded from the caller.
        let (wi, pdf) = unsafe { (floats_mut(wi, 3, "wi")?, floats_mut(pdf, 1, "pdf")?) };
        wi.fill(0.0);
        pdf[0] = 0.0;
        // SAFETY: forwarded from the caller.
        let (s, wo, u) = unsafe { (object(s, "sampler")?, vec3(wo, "wo")?, floats(u, 2, "u")?) };
        Ok(match s.sampler.sample(wo, Vec2::new(u[0], u[1])) {
            Some(d) => {
                wi.copy_from_slice(&d.wi.to_array());
                pdf[0] = d.pdf;
                1
            }
            None => 0,
        })
    })
}

/// The density per unit solid angle with which the sampler draws `wi`
/// given `wo`; 0 below the horizon and on failure.
///
/// # Safety
/// `s` is a live sampler; `wo` and `wi` point to 3 floats.
#[no_mangle]
pub unsafe extern "C" fn acdf_sampler_pdf(
    s: *const AcdfSampler,
    wo: *const f32,
    wi: *const f32,
) -> f32 {
    guarded(0.0, || {
        // SAFETY: forwarded from the caller.
        let (s, wo, wi) = unsafe { (object(s, "sampler")?, vec3(wo, "wo")?, vec3(wi, "wi")?) };
        Ok(s.sampler.pdf(wo, wi))
    })
}

/// `n` draws for one `wo`: `u` holds n pairs (2n floats), `wi` receives n
/// directions (3n floats) and `pdf` n densities (0 for no draw, with a zero
/// direction). Returns the number of valid draws (0 on failure).
///
/// # Safety
/// `s` is a live sampler; `wo` points to 3 floats, `u` to 2n; `wi` to 3n
/// writable floats and `pdf` to n.
#[no_mangle]
pub unsafe extern "C" fn acdf_sampler_sample_batch(
    s: *const AcdfSampler,
    wo: *const f32,
    u: *const f32,
    n: usize,
    wi: *mut f32,
    pdf: *mut f32,
) -> usize {
    guarded(0, || {
        let count = |k: usize| {
            n.checked_mul(k)
                .ok_or_else(|| format!("n = {n} is too large"))
        };
        // SAFETY: forwarded from the caller.
        let (s, wo) = unsafe { (object(s, "sampler")?, vec3(wo, "wo")?) };
        // SAFETY: forwarded from the caller.
        let (u, wi, pdf) = unsafe {
            (
                floats(u, count(2)?, "u")?,
                floats_mut(wi, count(3)?, "wi")?,
                floats_mut(pdf, n, "pdf")?,
            )
        };
        const CHUNK: usize = 256;
        let mut pairs = [Vec2::ZERO; CHUNK];
        let mut draws: [Option<BxdfSample>; CHUNK] = [None; CHUNK];
        let mut valid = 0;
        for start in (0..n).step_by(CHUNK) {
            let len = CHUNK.min(n - start);
            for (k, p) in pairs[..len].iter_mut().enumerate() {
                *p = Vec2::new(u[2 * (start + k)], u[2 * (start + k) + 1]);
            }
            s.sampler.sample_batch(wo, &pairs[..len], &mut draws[..len]);
            for (k, d) in draws[..len].iter().enumerate() {
                let i = start + k;
                let (dir, density) = match d {
                    Some(d) => {
                        valid += 1;
                        (d.wi, d.pdf)
                    }
                    None => (Vec3::ZERO, 0.0),
                };
                wi[3 * i..3 * i + 3].copy_from_slice(&dir.to_array());
                pdf[i] = density;
            }
        }
        Ok(valid)
    })
}

/// The bytes of the sampler's tables (what is built so far, for samplers
/// that build on first use); 0 on failure.
///
/// # Safety
/// `s` is a live sampler.
#[no_mangle]
pub unsafe extern "C" fn acdf_sampler_storage_bytes(s: *const AcdfSampler) -> usize {
    guarded(0, || {
        // SAFETY: forwarded from the caller.
        Ok(unsafe { object(s, "sampler") }?.sampler.storage_bytes())
    })
}

/// Load a lat-long environment map (Radiance `.hdr` or OpenEXR), refused as
/// the acdf command refuses it (not lat-long, NaN or negative texels, black
/// everywhere). NULL on failure.
///
/// # Safety
/// `path` is a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn acdf_envmap_load(path: *const c_char) -> *mut AcdfEnvMap {
    guarded(std::ptr::null_mut(), || {
        // SAFETY: forwarded from the caller.
        let path = Path::new(unsafe { text(path, "path") }?);
        let map = acdf::env_registry::load_env_map(path).map_err(|e| e.to_string())?;
        Ok(handle(AcdfEnvMap { map }))
    })
}

/// Free an environment map (NULL is ignored). Free its samplers first.
///
/// # Safety
/// `map` is NULL or a map not yet freed.
#[no_mangle]
pub unsafe extern "C" fn acdf_envmap_free(map: *mut AcdfEnvMap) {
    // SAFETY: forwarded from the caller.
    unsafe { free(map) }
}

/// The map's radiance (RGB) towards `dir` (3 floats, the map's frame),
/// nearest texel, into `rgb`; zeros on failure.
///
/// # Safety
/// `map` is a live map; `dir` points to 3 floats and `rgb` to 3 writable
/// floats.
#[no_mangle]
pub unsafe extern "C" fn acdf_envmap_radiance(
    map: *const AcdfEnvMap,
    dir: *const f32,
    rgb: *mut f32,
) {
    guarded((), || {
        // SAFETY: forwarded from the caller.
        let out = unsafe { floats_mut(rgb, 3, "rgb") }?;
        out.fill(0.0);
        // SAFETY: forwarded from the caller.
        let (map, dir) = unsafe { (object(map, "map")?, vec3(dir, "dir")?) };
        out.copy_from_slice(&map.map.radiance(dir).to_array());
        Ok(())
    })
}

/// A sampler of directions towards `map` by any environment sampler name
/// of the acdf command (`uniform`, `uniform-comp`, `adaptive:dp`,
/// `oriented:dp`, ...), with the command's default options. NULL on
/// failure.
///
/// # Safety
/// `map` is a live map; `name` a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn acdf_env_sampler_new(
    map: *const AcdfEnvMap,
    name: *const c_char,
) -> *mut AcdfEnvSampler {
    guarded(std::ptr::null_mut(), || {
        // SAFETY: forwarded from the caller.
        let (map, name) = unsafe { (object(map, "map")?, text(name, "name")?) };
        let sampler = make_env_sampler(name, &map.map, &EnvSamplerOptions::default())
            .map_err(|e| e.to_string())?;
        Ok(handle(AcdfEnvSampler { sampler }))
    })
}

/// Free an environment sampler (NULL is ignored).
///
/// # Safety
/// `s` is NULL or an environment sampler not yet freed.
#[no_mangle]
pub unsafe extern "C" fn acdf_env_sampler_free(s: *mut AcdfEnvSampler) {
    // SAFETY: forwarded from the caller.
    unsafe { free(s) }
}

/// The shading normal behind `p`: NULL for none.
///
/// # Safety
/// As [`vec3`].
unsafe fn normal(p: *const f32) -> Result<Option<Vec3>, String> {
    if p.is_null() {
        Ok(None)
    } else {
        // SAFETY: forwarded.
        unsafe { vec3(p, "normal") }.map(Some)
    }
}

/// Draw a direction towards the map from the uniform pair `u`, for the
/// shading normal `normal` (3 floats in the map's frame, or NULL for
/// none; the orientation-aware samplers use it): 1 with the direction in
/// `dir` and its density in `pdf`, 0 for no draw or a failure (zeros). The
/// same numbers as `acdf env-sample` for the same normal and u.
///
/// # Safety
/// `s` is a live environment sampler; `normal` is NULL or points to 3
/// floats, `u` to 2; `dir` to 3 writable floats and `pdf` to one.
#[no_mangle]
pub unsafe extern "C" fn acdf_env_sampler_sample(
    s: *const AcdfEnvSampler,
    normal: *const f32,
    u: *const f32,
    dir: *mut f32,
    pdf: *mut f32,
) -> c_int {
    guarded(0, || {
        // SAFETY: forwarded from the caller.
        let (dir, pdf) = unsafe { (floats_mut(dir, 3, "dir")?, floats_mut(pdf, 1, "pdf")?) };
        dir.fill(0.0);
        pdf[0] = 0.0;
        // SAFETY: forwarded from the caller.
        let (s, n, u) = unsafe {
            (
                object(s, "environment sampler")?,
                self::normal(normal)?,
                floats(u, 2, "u")?,
            )
        };
        Ok(match s.sampler.sample(n, Vec2::new(u[0], u[1])) {
            Some(d) => {
                dir.copy_from_slice(&d.dir.to_array());
                pdf[0] = d.pdf;
                1
            }
            None => 0,
        })
    })
}

/// The density per unit solid angle with which the environment sampler
/// draws `dir` for the shading normal `normal` (NULL for none); 0 on
/// failure.
///
/// # Safety
/// `s` is a live environment sampler; `normal` is NULL or points to 3
/// floats; `dir` points to 3 floats.
#[no_mangle]
pub unsafe extern "C" fn acdf_env_sampler_pdf(
    s: *const AcdfEnvSampler,
    normal: *const f32,
    dir: *const f32,
) -> f32 {
    guarded(0.0, || {
        // SAFETY: forwarded from the caller.
        let (s, n, dir) = unsafe {
            (
                object(s, "environment sampler")?,
                self::normal(normal)?,
                vec3(dir, "dir")?,
            )
        };
        Ok(s.sampler.pdf(n, dir))
    })
}
