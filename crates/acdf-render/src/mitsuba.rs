//! The scene of `acdf render` as a Mitsuba 3 scene: the same camera,
//! sphere, ground plane and environment, so that Mitsuba renders the image
//! acdf renders (up to Monte Carlo noise).
//!
//! Two conventions differ and are translated here:
//!
//! - Mitsuba's `envmap` maps its image with `+y` up and φ = 0 along `−z`,
//!   turning from `−z` towards `+x`; acdf's ([`acdf_lights::latlong`]) has
//!   `+z` up and φ = 0 along `+x`, turning towards `+y`. The emitter's
//!   `to_world` is the matrix [`ENVMAP_TO_WORLD`] that sends Mitsuba's
//!   direction of (θ, φ) to acdf's direction of the same (θ, φ): (x, y, z)
//!   ↦ (−z, x, y). It is a reflection (determinant −1), since the two
//!   azimuths turn in opposite senses about the pole.
//! - acdf looks a map up by nearest texel, texel (k, j) covering θ ∈
//!   [πj/H, π(j+1)/H); Mitsuba interpolates bilinearly between pixel
//!   values placed at θ = πj/(H−1), with the periodic column added. The
//!   exported image is therefore acdf's map resampled: s × W columns and
//!   s × H + 1 rows ([`mitsuba_map`]), each holding the texel of acdf's map
//!   its position falls in, or the mean of the two texels for a row that
//!   falls on a texel boundary. Mitsuba's interpolation then blends only
//!   across bands of 1/s texel centred on acdf's texel edges, where it
//!   loses on one side what it adds on the other.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use acdf_core::Rgb;
use acdf_lights::EnvMap;

use crate::render::{
    CAMERA_EYE, CAMERA_FOV_X_DEGREES, CAMERA_TARGET, PLANE_ALBEDO, PLANE_HALF_SIZE, PLANE_Z,
    SPHERE_RADIUS,
};
use acdf::error::{Error, Result};
use acdf::spec::MaterialSpec;

/// The `to_world` of Mitsuba's `envmap` that gives it acdf's convention,
/// row-major 4 × 4: (x, y, z) ↦ (−z, x, y).
pub const ENVMAP_TO_WORLD: [f32; 16] = [
    0.0, 0.0, -1.0, 0.0, //
    1.0, 0.0, 0.0, 0.0, //
    0.0, 1.0, 0.0, 0.0, //
    0.0, 0.0, 0.0, 1.0,
];

/// The widest exported map: the factor s of [`mitsuba_map`] is the largest
/// of 1 to 8 that keeps s × W at most this.
pub const MAX_EXPORT_WIDTH: usize = 2048;

/// The resampling factor for a map `width` texels wide.
pub fn export_factor(width: usize) -> usize {
    (MAX_EXPORT_WIDTH / width.max(1)).clamp(1, 8)
}

/// acdf's map resampled for Mitsuba's vertex-interpolated lookup: s × W by
/// s × H + 1 pixels; pixel (k', j') lies at φ = 2π(k' + ½)/(sW) and θ =
/// πj'/(sH) and holds the texel of `map` there, or the mean of the two
/// texels above and below when j' is a multiple of s inside the map.
pub fn mitsuba_map(map: &EnvMap, s: usize) -> image::Rgb32FImage {
    let (w, h) = map.size();
    let s = s.max(1);
    let texels = map.texels();
    let texel = |k: usize, j: usize| texels[j * w + k];
    let mut img = image::Rgb32FImage::new((s * w) as u32, (s * h + 1) as u32);
    for (kp, jp, px) in img.enumerate_pixels_mut() {
        let (kp, jp) = (kp as usize, jp as usize);
        let k = kp / s;
        let v: Rgb = if jp % s == 0 {
            let j = jp / s;
            match (j.checked_sub(1), (j < h).then_some(j)) {
                (Some(a), Some(b)) => 0.5 * (texel(k, a) + texel(k, b)),
                (Some(a), None) => texel(k, a),
                (None, Some(b)) => texel(k, b),
                (None, None) => Rgb::ZERO,
            }
        } else {
            texel(k, jp / s)
        };
        px.0 = v.to_array();
    }
    img
}

/// What [`export`] needs of the scene.
#[derive(Debug, Clone)]
pub struct ExportScene<'a> {
    /// The sphere's material (an RGL file or `builtin:lambert`).
    pub material: &'a MaterialSpec,
    /// The environment, in acdf's convention.
    pub map: &'a EnvMap,
    /// Whether the ground plane is there.
    pub plane: bool,
    /// Image size in pixels.
    pub width: usize,
    pub height: usize,
    /// The default samples per pixel (`$spp` overrides it).
    pub spp: usize,
}

/// The Mitsuba BSDF of a material: `measured` for an RGL file (by absolute
/// path), `diffuse` of albedo 0.8 for `builtin:lambert`; an error naming
/// the material for any other.
fn bsdf_xml(material: &MaterialSpec) -> Result<String> {
    match material {
        MaterialSpec::Rgl(path) => {
            let abs = std::fs::canonicalize(path).map_err(|e| Error::io(path, e))?;
            Ok(format!(
                "<bsdf type=\"measured\"><string name=\"filename\" value=\"{}\"/></bsdf>",
                xml_escape(&abs.to_string_lossy())
            ))
        }
        MaterialSpec::Builtin(name) if name == "lambert" => Ok(
            "<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.8\"/></bsdf>".to_string(),
        ),
        other => Err(Error::InvalidArgument {
            what: "material",
            value: other.to_string(),
            reason: "--export-mitsuba writes RGL .bsdf files (Mitsuba's `measured`) and \
                     builtin:lambert (`diffuse`) only; Mitsuba 3 has no plug-in for the others"
                .into(),
        }),
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

fn triple(v: [f32; 3]) -> String {
    format!("{}, {}, {}", v[0], v[1], v[2])
}

/// The scene file's text, with the map in `envmap.exr` beside it.
pub fn scene_xml(scene: &ExportScene) -> Result<String> {
    let mut x = String::new();
    let matrix: Vec<String> = ENVMAP_TO_WORLD.iter().map(|v| v.to_string()).collect();
    let w = |x: &mut String, s: &str| {
        x.push_str(s);
        x.push('\n');
    };
    w(&mut x, "<scene version=\"3.0.0\">");
    w(
        &mut x,
        "    <!-- acdf render --export-mitsuba: direct light only (path tracing to depth 2). -->",
    );
    let _ = writeln!(
        x,
        "    <default name=\"spp\" value=\"{}\"/>",
        scene.spp.max(1)
    );
    w(
        &mut x,
        "    <integrator type=\"path\"><integer name=\"max_depth\" value=\"2\"/></integrator>",
    );
    w(&mut x, "    <sensor type=\"perspective\">");
    let _ = writeln!(
        x,
        "        <float name=\"fov\" value=\"{CAMERA_FOV_X_DEGREES}\"/>"
    );
    w(&mut x, "        <string name=\"fov_axis\" value=\"x\"/>");
    let _ = writeln!(
        x,
        "        <transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"0, 0, 1\"/></transform>",
        triple(CAMERA_EYE),
        triple(CAMERA_TARGET)
    );
    w(
        &mut x,
        "        <sampler type=\"independent\"><integer name=\"sample_count\" value=\"$spp\"/></sampler>",
    );
    let _ = writeln!(
        x,
        "        <film type=\"hdrfilm\"><integer name=\"width\" value=\"{}\"/><integer name=\"height\" value=\"{}\"/><rfilter type=\"box\"/><string name=\"pixel_format\" value=\"rgb\"/></film>",
        scene.width, scene.height
    );
    w(&mut x, "    </sensor>");
    let _ = writeln!(
        x,
        "    <shape type=\"sphere\"><point name=\"center\" x=\"0\" y=\"0\" z=\"0\"/><float name=\"radius\" value=\"{SPHERE_RADIUS}\"/>{}</shape>",
        bsdf_xml(scene.material)?
    );
    if scene.plane {
        let _ = writeln!(
            x,
            "    <shape type=\"rectangle\"><transform name=\"to_world\"><scale x=\"{PLANE_HALF_SIZE}\" y=\"{PLANE_HALF_SIZE}\" z=\"1\"/><translate x=\"0\" y=\"0\" z=\"{PLANE_Z}\"/></transform><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"{PLANE_ALBEDO}\"/></bsdf></shape>"
        );
    }
    let _ = writeln!(
        x,
        "    <emitter type=\"envmap\"><string name=\"filename\" value=\"envmap.exr\"/><transform name=\"to_world\"><matrix value=\"{}\"/></transform></emitter>",
        matrix.join(" ")
    );
    w(&mut x, "</scene>");
    Ok(x)
}

/// Encode a float RGB image as OpenEXR bytes.
pub fn exr_bytes(img: &image::Rgb32FImage, name: &Path) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    image::DynamicImage::ImageRgb32F(img.clone())
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::OpenExr,
        )
        .map_err(|e| Error::Image {
            path: name.to_path_buf(),
            message: e.to_string(),
        })?;
    Ok(bytes)
}

/// Write the scene into `dir` (created if missing): `scene.xml` and
/// `envmap.exr`, each atomically. Returns the scene file's path.
pub fn export(dir: &Path, scene: &ExportScene) -> Result<PathBuf> {
    let xml = scene_xml(scene)?;
    acdf_io::fsio::ensure_folder(dir)?;
    let map_path = dir.join("envmap.exr");
    let img = mitsuba_map(scene.map, export_factor(scene.map.size().0));
    let bytes = exr_bytes(&img, &map_path)?;
    acdf_io::fsio::write_atomic(&map_path, |w| w.write_all(&bytes))?;
    let path = dir.join("scene.xml");
    acdf_io::fsio::write_atomic(&path, |w| w.write_all(xml.as_bytes()))?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::Vec3;

    /// The matrix sends Mitsuba's direction of (θ, φ), (sin φ sin θ, cos θ,
    /// −cos φ sin θ), to acdf's, (sin θ cos φ, sin θ sin φ, cos θ).
    #[test]
    fn envmap_transform_matches_the_conventions() {
        let m = &ENVMAP_TO_WORLD;
        for (t, p) in [(0.3f32, 0.2f32), (1.2, 2.5), (2.8, 5.9), (1.57, 4.0)] {
            let mi = Vec3::new(p.sin() * t.sin(), t.cos(), -p.cos() * t.sin());
            let acdf = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
            let got = Vec3::new(
                m[0] * mi.x + m[1] * mi.y + m[2] * mi.z,
                m[4] * mi.x + m[5] * mi.y + m[6] * mi.z,
                m[8] * mi.x + m[9] * mi.y + m[10] * mi.z,
            );
            assert!((got - acdf).length() < 1e-6, "{got} {acdf}");
        }
    }

    /// Resampling keeps each texel's value inside it and averages on the
    /// row boundaries; the first and last rows are the poles' texels.
    #[test]
    fn resampled_map_holds_the_texels() {
        let map = EnvMap::from_fn(4, 2, |k, j| Rgb::new(k as f32, j as f32, 1.0)).unwrap();
        let img = mitsuba_map(&map, 2);
        assert_eq!(img.dimensions(), (8, 5));
        assert_eq!(img.get_pixel(3, 1).0, [1.0, 0.0, 1.0]);
        assert_eq!(img.get_pixel(3, 2).0, [1.0, 0.5, 1.0]);
        assert_eq!(img.get_pixel(7, 0).0, [3.0, 0.0, 1.0]);
        assert_eq!(img.get_pixel(7, 4).0, [3.0, 1.0, 1.0]);
    }

    #[test]
    fn only_rgl_and_lambert_export() {
        let map = EnvMap::from_fn(4, 2, |_, _| Rgb::ONE).unwrap();
        let scene = |m| ExportScene {
            material: m,
            map: &map,
            plane: true,
            width: 8,
            height: 6,
            spp: 4,
        };
        let lambert = MaterialSpec::Builtin("lambert".into());
        let xml = scene_xml(&scene(&lambert)).unwrap();
        assert!(xml.contains("diffuse") && xml.contains("rectangle") && xml.contains("envmap"));
        let nickel = MaterialSpec::Builtin("nickel".into());
        assert!(scene_xml(&scene(&nickel)).is_err());
    }
}
