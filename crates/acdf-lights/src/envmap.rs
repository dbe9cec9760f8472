//! Environment maps: a latitude-longitude HDR image read from a Radiance
//! `.hdr` or OpenEXR file, looked up by direction.

use std::path::Path;

use acdf_core::{luminance, Rgb, Vec2, Vec3};

use crate::error::{EnvError, Result};
use crate::latlong::LatLong;

/// A latitude-longitude environment map in linear Rec. 709 RGB, with the
/// convention of [`latlong`](crate::latlong): `+z` up, row 0 at the zenith,
/// column 0 starting at φ = 0 (the `+x` axis), φ growing towards `+y`.
///
/// Every texel is finite and non-negative: the constructors reject NaN,
/// infinite and negative values ([`EnvError::NonFinite`],
/// [`EnvError::Negative`]); [`EnvMap::open_repaired`] and
/// [`EnvMap::from_rgb_repaired`] set them to 0 instead and count them.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvMap {
    grid: LatLong,
    rgb: Vec<Rgb>,
    luminance: Vec<f32>,
}

/// What [`EnvMap::from_rgb_repaired`] replaced by 0, in channel values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Repairs {
    pub non_finite: usize,
    pub negative: usize,
}

impl Repairs {
    /// Whether nothing was replaced.
    pub fn is_empty(&self) -> bool {
        self.non_finite == 0 && self.negative == 0
    }
}

/// Check the dimensions of a lat-long map: at least one texel, twice as
/// wide as high (or 1x1), and `len` texels.
fn check_size(width: usize, height: usize, len: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(EnvError::Empty { width, height });
    }
    if width != 2 * height && !(width == 1 && height == 1) {
        return Err(EnvError::NotLatLong { width, height });
    }
    let expected = width
        .checked_mul(height)
        .ok_or(EnvError::NotLatLong { width, height })?;
    if len != expected {
        return Err(EnvError::SizeMismatch {
            width,
            height,
            expected,
            got: len,
        });
    }
    Ok(())
}

impl EnvMap {
    /// A map from row-major texels (`height` rows of `width`), which must
    /// be twice as wide as high (or 1x1) and finite and non-negative in
    /// every channel.
    pub fn from_rgb(width: usize, height: usize, texels: Vec<Rgb>) -> Result<EnvMap> {
        check_size(width, height, texels.len())?;
        let channel = |t: &Rgb| t.to_array();
        let non_finite = texels
            .iter()
            .flat_map(channel)
            .filter(|c| !c.is_finite())
            .count();
        if let Some(i) = texels.iter().position(|t| !t.is_finite()) {
            let value = channel(&texels[i])
                .into_iter()
                .find(|c| !c.is_finite())
                .unwrap_or(f32::NAN);
            return Err(EnvError::NonFinite {
                column: i % width,
                row: i / width,
                value,
                count: non_finite,
            });
        }
        let negative = texels.iter().flat_map(channel).filter(|&c| c < 0.0).count();
        if let Some(i) = texels.iter().position(|t| t.min_element() < 0.0) {
            return Err(EnvError::Negative {
                column: i % width,
                row: i / width,
                value: texels[i].min_element(),
                count: negative,
            });
        }
        Ok(Self::from_checked(width, height, texels))
    }

    /// [`from_rgb`](Self::from_rgb), but NaN, infinite and negative channel
    /// values become 0 (counted in the returned [`Repairs`]) instead of
    /// errors. Wrong dimensions are still errors.
    pub fn from_rgb_repaired(
        width: usize,
        height: usize,
        mut texels: Vec<Rgb>,
    ) -> Result<(EnvMap, Repairs)> {
        check_size(width, height, texels.len())?;
        let mut repairs = Repairs::default();
        for t in &mut texels {
            for c in t.as_mut() {
                if !c.is_finite() {
                    repairs.non_finite += 1;
                    *c = 0.0;
                } else if *c < 0.0 {
                    repairs.negative += 1;
                    *c = 0.0;
                }
            }
        }
        Ok((Self::from_checked(width, height, texels), repairs))
    }

    fn from_checked(width: usize, height: usize, rgb: Vec<Rgb>) -> EnvMap {
        let luminance = rgb.iter().map(|&c| luminance(c).max(0.0)).collect();
        EnvMap {
            grid: LatLong::new(width, height),
            rgb,
            luminance,
        }
    }

    /// A map whose texel (column, row) is `f(column, row)`, checked as
    /// [`from_rgb`](Self::from_rgb) checks it.
    pub fn from_fn(width: usize, height: usize, f: impl Fn(usize, usize) -> Rgb) -> Result<EnvMap> {
        let texels = (0..height)
            .flat_map(|j| (0..width).map(move |k| (k, j)))
            .map(|(k, j)| f(k, j))
            .collect();
        Self::from_rgb(width, height, texels)
    }

    /// Read a Radiance `.hdr` or OpenEXR file (the format is recognised
    /// from the content, then the extension) and check it as
    /// [`from_rgb`](Self::from_rgb) does.
    pub fn open(path: &Path) -> Result<EnvMap> {
        let (w, h, texels) = read_rgb(path)?;
        Self::from_rgb(w, h, texels)
    }

    /// [`open`](Self::open), with NaN, infinite and negative channel values
    /// set to 0 as [`from_rgb_repaired`](Self::from_rgb_repaired) does.
    pub fn open_repaired(path: &Path) -> Result<(EnvMap, Repairs)> {
        let (w, h, texels) = read_rgb(path)?;
        Self::from_rgb_repaired(w, h, texels)
    }

    /// Width and height in texels.
    pub fn size(&self) -> (usize, usize) {
        self.grid.size()
    }

    /// The texel grid and its mapping to directions.
    pub fn grid(&self) -> &LatLong {
        &self.grid
    }

    /// The texels, row-major.
    pub fn texels(&self) -> &[Rgb] {
        &self.rgb
    }

    /// The luminance of every texel, row-major.
    pub fn luminance(&self) -> &[f32] {
        &self.luminance
    }

    /// Whether every texel is black: such a map emits nothing, and its
    /// samplers fall back to uniform directions over the sphere.
    pub fn is_black(&self) -> bool {
        self.luminance.iter().all(|&y| y <= 0.0)
    }

    /// ∫ Y(L(ω)) dω over the sphere (luminance, nearest-texel radiance), in
    /// f64.
    pub fn luminance_integral(&self) -> f64 {
        let (w, _) = self.size();
        self.luminance
            .chunks_exact(w)
            .enumerate()
            .map(|(j, row)| {
                self.grid.texel_solid_angle(j) * row.iter().map(|&y| y as f64).sum::<f64>()
            })
            .sum()
    }

    /// L(dir): the texel holding `dir` (nearest lookup). This is the
    /// radiance the samplers' tables follow. 0 for a direction that is not
    /// finite or has no length.
    #[inline]
    pub fn radiance(&self, dir: Vec3) -> Rgb {
        match self.grid.texel_of(dir) {
            Some((k, j)) => self.rgb[j * self.grid.size().0 + k],
            None => Rgb::ZERO,
        }
    }

    /// L(dir) interpolated bilinearly between the four nearest texel
    /// centres in (φ, θ): wrapping around in φ, clamped at the top and
    /// bottom rows. Smoother for display; its energy differs slightly from
    /// the nearest lookup the samplers follow.
    pub fn radiance_bilinear(&self, dir: Vec3) -> Rgb {
        if (dir * 0.0).element_sum() != 0.0 || dir == Vec3::ZERO {
            return Rgb::ZERO;
        }
        let (w, h) = self.size();
        let d = dir.normalize();
        let phi = acdf_core::geometry::phi(d) as f64;
        let theta = acdf_core::geometry::theta(d) as f64;
        let x = phi / std::f64::consts::TAU * w as f64 - 0.5;
        let y = (theta / std::f64::consts::PI * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let col = |c: f64| (c as i64).rem_euclid(w as i64) as usize;
        let (c0, c1) = (col(x0), col(x0 + 1.0));
        let r0 = y0 as usize;
        let r1 = (r0 + 1).min(h - 1);
        let t = |c: usize, r: usize| self.rgb[r * w + c];
        let top = t(c0, r0).lerp(t(c1, r0), fx);
        let bottom = t(c0, r1).lerp(t(c1, r1), fx);
        top.lerp(bottom, fy).max(Rgb::ZERO)
    }

    /// The texel (column, row) holding `dir`, see
    /// [`LatLong::texel_of`].
    pub fn texel_of(&self, dir: Vec3) -> Option<(usize, usize)> {
        self.grid.texel_of(dir)
    }

    /// The direction of a point of the unit square, see
    /// [`LatLong::direction_of_point`].
    pub fn direction_of(&self, p: Vec2) -> Vec3 {
        self.grid.direction_of_point(p).0
    }
}

/// Bytes read before the image's size is known: more than the header of
/// a Radiance or OpenEXR file needs.
const HEADER_BYTES: usize = 64 << 10;

/// Bytes per texel at the peak of decoding a map: the decoder's f32 image
/// (up to four channels, 16), its RGB copy (12), the map's texels (12) and
/// luminance (4).
const DECODE_BYTES_PER_TEXEL: u64 = 44;

/// The most bytes a file of a given size in texels may hold: 32 per texel
/// (a 32-bit RGBA OpenEXR image takes 16, a Radiance file 4 or a little
/// more) and 1 MiB of header and offset tables.
fn max_file_bytes(texels: u64) -> u64 {
    acdf_io::limits::bytes_of(texels, 32).saturating_add(1 << 20)
}

/// The image format of a file: from its first bytes, else from the
/// extension of `path`.
fn image_format(head: &[u8], path: &Path) -> Result<image::ImageFormat> {
    image::guess_format(head)
        .or_else(|_| image::ImageFormat::from_path(path))
        .map_err(|_| EnvError::Decode {
            path: path.to_path_buf(),
            message: "not an image (neither a Radiance .hdr nor an OpenEXR file)".into(),
        })
}

fn decode_error(path: &Path) -> impl Fn(image::ImageError) -> EnvError + '_ {
    move |e| EnvError::Decode {
        path: path.to_path_buf(),
        message: match e {
            image::ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                "the file ends before the image does (truncated)".to_string()
            }
            e => e.to_string().replace('\n', " "),
        },
    }
}

/// The format and size of the image whose first bytes are `head`, read
/// from its header alone, checked before anything is decoded: a
/// lat-long size ([`check_size`]) whose decoding fits in the memory limit
/// (`acdf_io::limits`).
fn read_header(head: &[u8], path: &Path) -> Result<(image::ImageFormat, usize, usize)> {
    let format = image_format(head, path)?;
    if format == image::ImageFormat::OpenExr {
        check_exr_windows(head, path)?;
    }
    let (w, h) = image::ImageReader::with_format(std::io::Cursor::new(head), format)
        .into_dimensions()
        .map_err(decode_error(path))?;
    let (w, h) = (w as usize, h as usize);
    check_size(w, h, w * h)?;
    acdf_io::limits::check_memory(
        &format!("decoding the {w}x{h} environment map"),
        acdf_io::limits::bytes_of((w * h) as u64, DECODE_BYTES_PER_TEXEL),
    )?;
    Ok((format, w, h))
}

/// An OpenEXR header's data and display windows (`box2i` attributes:
/// x_min, y_min, x_max, y_max as little-endian `i32`) must not be
/// inverted: a window whose maximum is below its minimum has no pixels, and
/// a decoder may still make an image of it. The attributes are found by
/// walking the header's (name, type, size, value) list from byte 8.
fn check_exr_windows(head: &[u8], path: &Path) -> Result<()> {
    let invalid = |message: String| EnvError::Decode {
        path: path.to_path_buf(),
        message,
    };
    let text = |bytes: &[u8], at: usize| -> Option<(Vec<u8>, usize)> {
        let end = at + bytes.get(at..)?.iter().position(|&b| b == 0)?;
        Some((bytes[at..end].to_vec(), end + 1))
    };
    let mut at = 8;
    // The attribute list ends with an empty name; a header cut by `head`
    // (64 KiB) ends the walk without a verdict.
    while let Some((name, after_name)) = text(head, at) {
        if name.is_empty() {
            break;
        }
        let Some((kind, after_kind)) = text(head, after_name) else {
            break;
        };
        let Some(size) = head
            .get(after_kind..after_kind + 4)
            .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        else {
            break;
        };
        let value = after_kind + 4;
        let Ok(size) = usize::try_from(size) else {
            return Err(invalid(format!("attribute of negative size {size}")));
        };
        if kind == b"box2i" && size == 16 && (name == b"dataWindow" || name == b"displayWindow") {
            let Some(v) = head.get(value..value + 16) else {
                break;
            };
            let n =
                |k: usize| i32::from_le_bytes([v[4 * k], v[4 * k + 1], v[4 * k + 2], v[4 * k + 3]]);
            let (x0, y0, x1, y1) = (n(0), n(1), n(2), n(3));
            if x1 < x0 || y1 < y0 {
                return Err(invalid(format!(
                    "the {} is inverted (x {x0}..{x1}, y {y0}..{y1}): it holds no pixels",
                    String::from_utf8_lossy(&name)
                )));
            }
        }
        at = value.saturating_add(size);
    }
    Ok(())
}

/// Decode a whole image file held in `bytes` to linear RGB texels, with
/// the decoder's own allocations bounded by the memory limit too.
fn decode_rgb(
    bytes: &[u8],
    format: image::ImageFormat,
    path: &Path,
) -> Result<(usize, usize, Vec<Rgb>)> {
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(acdf_io::limits::memory_limit());
    reader.limits(limits);
    let img = reader.decode().map_err(decode_error(path))?;
    let rgb = img.to_rgb32f();
    drop(img);
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let texels = rgb
        .pixels()
        .map(|p| Vec3::new(p.0[0], p.0[1], p.0[2]))
        .collect();
    Ok((w, h, texels))
}

/// Read an image file to linear RGB texels through
/// `acdf_io::fsio::Input`: the header first (at most 64 KiB, so that a
/// device such as /dev/zero is refused from its first bytes), its size
/// checked ([`read_header`]), then the rest of the file, bounded by what
/// an image of that size can hold.
fn read_rgb(path: &Path) -> Result<(usize, usize, Vec<Rgb>)> {
    let mut input = acdf_io::fsio::Input::open(path)?;
    let mut bytes = input.read_up_to(HEADER_BYTES)?;
    let (format, w, h) = read_header(&bytes, path)?;
    let max = max_file_bytes((w * h) as u64)
        .min(acdf_io::limits::memory_limit())
        .saturating_sub(bytes.len() as u64);
    let rest = input.read_rest(max, &format!("what a {w}x{h} image file holds"))?;
    bytes.extend_from_slice(&rest);
    drop(rest);
    decode_rgb(&bytes, format, path)
}

impl EnvMap {
    /// A map from the bytes of a whole Radiance `.hdr` or OpenEXR file
    /// (`path` names it in errors and gives the format when the bytes do
    /// not), checked as [`open`](Self::open) checks a file: the size from
    /// the header against the memory limit before decoding, then the
    /// texels as [`from_rgb`](Self::from_rgb) does.
    pub fn from_file_bytes(bytes: &[u8], path: &Path) -> Result<EnvMap> {
        let (format, _, _) = read_header(&bytes[..bytes.len().min(HEADER_BYTES)], path)?;
        let (w, h, texels) = decode_rgb(bytes, format, path)?;
        Self::from_rgb(w, h, texels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An EXR whose data window was inverted (its maximum below its
    /// minimum) is refused, naming the window; the file it came from loads.
    #[test]
    fn an_inverted_exr_data_window_is_refused() {
        let img = image::Rgb32FImage::from_pixel(8, 4, image::Rgb([1.0, 0.5, 0.25]));
        let mut bytes = Vec::new();
        image::DynamicImage::ImageRgb32F(img)
            .write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::OpenExr,
            )
            .unwrap();
        let path = Path::new("sky.exr");
        assert!(EnvMap::from_file_bytes(&bytes, path).is_ok());
        let tag = b"dataWindow\0box2i\0";
        let at = bytes
            .windows(tag.len())
            .position(|w| w == tag)
            .expect("a data window")
            + tag.len()
            + 4;
        // (0, 0, 7, 3) becomes (7, 0, 0, 3).
        let mut inverted = bytes.clone();
        inverted[at..at + 4].copy_from_slice(&7i32.to_le_bytes());
        inverted[at + 8..at + 12].copy_from_slice(&0i32.to_le_bytes());
        let err = EnvMap::from_file_bytes(&inverted, path).unwrap_err();
        assert!(err.to_string().contains("dataWindow is inverted"), "{err}");
    }

    #[test]
    fn sizes_are_checked() {
        assert!(matches!(
            EnvMap::from_rgb(0, 0, vec![]),
            Err(EnvError::Empty { .. })
        ));
        assert!(matches!(
            EnvMap::from_rgb(3, 2, vec![Rgb::ONE; 6]),
            Err(EnvError::NotLatLong {
                width: 3,
                height: 2
            })
        ));
        assert!(matches!(
            EnvMap::from_rgb(4, 2, vec![Rgb::ONE; 7]),
            Err(EnvError::SizeMismatch { .. })
        ));
        assert!(EnvMap::from_rgb(1, 1, vec![Rgb::ONE]).is_ok());
        assert!(EnvMap::from_rgb(2, 1, vec![Rgb::ONE; 2]).is_ok());
    }

    #[test]
    fn bad_texels_are_named_or_repaired() {
        let mut t = vec![Rgb::ONE; 8];
        t[5] = Rgb::new(1.0, f32::NAN, 0.0);
        t[6] = Rgb::new(f32::INFINITY, 1.0, 0.0);
        t[7] = Rgb::new(-1.0, 1.0, 0.0);
        match EnvMap::from_rgb(4, 2, t.clone()) {
            Err(
                e @ EnvError::NonFinite {
                    column: 1,
                    row: 1,
                    count: 2,
                    ..
                },
            ) => assert!(e.to_string().contains("row 1"), "{e}"),
            other => panic!("{other:?}"),
        }
        let mut neg = vec![Rgb::ONE; 8];
        neg[2] = Rgb::new(0.0, -0.5, 0.0);
        assert!(matches!(
            EnvMap::from_rgb(4, 2, neg),
            Err(EnvError::Negative {
                column: 2,
                row: 0,
                count: 1,
                ..
            })
        ));
        let (map, repairs) = EnvMap::from_rgb_repaired(4, 2, t).unwrap();
        assert_eq!(
            repairs,
            Repairs {
                non_finite: 2,
                negative: 1
            }
        );
        assert!(map
            .texels()
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0));
    }

    #[test]
    fn lookups_follow_the_convention() {
        // Row 0 bright, row 1 dim; column 1 of row 1 red.
        let map = EnvMap::from_fn(4, 2, |k, j| match (k, j) {
            (_, 0) => Rgb::splat(2.0),
            (1, 1) => Rgb::new(1.0, 0.0, 0.0),
            _ => Rgb::splat(0.5),
        })
        .unwrap();
        assert_eq!(map.radiance(Vec3::Z), Rgb::splat(2.0));
        assert_eq!(map.radiance(-Vec3::Z), Rgb::splat(0.5));
        // φ = 135°, below the horizon: column 1 of row 1.
        let d = Vec3::new(-1.0, 1.0, -0.5);
        assert_eq!(map.radiance(d), Rgb::new(1.0, 0.0, 0.0));
        assert_eq!(map.radiance(Vec3::ZERO), Rgb::ZERO);
        assert_eq!(map.radiance_bilinear(Vec3::NAN), Rgb::ZERO);
        // Bilinear lookups at texel centres (in θ and φ) are the texels.
        let c = acdf_core::geometry::spherical_direction(
            0.75 * std::f32::consts::PI,
            0.75 * std::f32::consts::PI,
        );
        assert!((map.radiance_bilinear(c) - Rgb::new(1.0, 0.0, 0.0)).length() < 1e-3);
        let mean = map.luminance_integral() / (4.0 * std::f64::consts::PI);
        assert!(mean > 0.5 && mean < 2.0);
    }

    #[test]
    fn files_that_are_not_maps_are_typed_errors() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("none.hdr");
        assert!(matches!(EnvMap::open(&missing), Err(EnvError::File(_))));
        let write = |name: &str, bytes: &[u8]| {
            let path = dir.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            path
        };
        let header =
            |w: u64, h: u64| format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n");
        // A truncated body.
        let junk = write("junk.hdr", &[header(8, 4).as_bytes(), b"\x02\x02"].concat());
        let e = EnvMap::open(&junk).unwrap_err();
        assert!(matches!(e, EnvError::Decode { .. }), "{e}");
        assert!(e.to_string().contains("truncated"), "{e}");
        // A huge declared size: refused from the header, before decoding.
        let huge = write("huge.hdr", header(1 << 20, 1 << 19).as_bytes());
        let e = EnvMap::open(&huge).unwrap_err();
        assert!(
            matches!(e, EnvError::Core(acdf_core::Error::MemoryLimit { .. })),
            "{e}"
        );
        // Not lat-long: refused from the header.
        let square = write("square.hdr", header(8, 8).as_bytes());
        let e = EnvMap::open(&square).unwrap_err();
        assert!(
            matches!(
                e,
                EnvError::NotLatLong {
                    width: 8,
                    height: 8
                }
            ),
            "{e}"
        );
        // Neither format, whatever the name says.
        let text = write("text.exr", b"hello");
        assert!(matches!(EnvMap::open(&text), Err(EnvError::Decode { .. })));
        assert!(matches!(
            EnvMap::from_file_bytes(b"", Path::new("empty.hdr")),
            Err(EnvError::Decode { .. })
        ));
        // A device: refused from its first bytes.
        #[cfg(unix)]
        {
            let e = EnvMap::open(Path::new("/dev/zero")).unwrap_err();
            assert!(matches!(e, EnvError::Decode { .. }), "{e}");
            let link = dir.path().join("zero.hdr");
            std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
            let e = EnvMap::open(&link).unwrap_err();
            assert!(matches!(e, EnvError::Decode { .. }), "{e}");
        }
        for e in [EnvMap::open(&huge), EnvMap::open(&junk)] {
            assert!(!e.unwrap_err().to_string().contains('\n'));
        }
    }

    /// A small map written as a Radiance file reads back the same through
    /// the file and the bytes forms.
    #[test]
    fn written_maps_read_back() {
        let pixel = |x: u32, y: u32| image::Rgb([x as f32 * 0.25, y as f32, 1.0 + (x * y) as f32]);
        let mut bytes = std::io::Cursor::new(Vec::new());
        image::Rgb32FImage::from_fn(16, 8, pixel)
            .write_to(&mut bytes, image::ImageFormat::Hdr)
            .unwrap();
        let bytes = bytes.into_inner();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("small.hdr");
        std::fs::write(&path, &bytes).unwrap();
        let a = EnvMap::open(&path).unwrap();
        let b = EnvMap::from_file_bytes(&bytes, &path).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.size(), (16, 8));
        let t = a.texels()[3 * 16 + 5];
        assert!((t - Rgb::new(1.25, 3.0, 16.0)).length() < 0.1, "{t}");
    }
}
