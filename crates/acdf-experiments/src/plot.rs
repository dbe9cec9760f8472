//! Figures: log-log charts (the efficiency- and variance-against-storage
//! plots of a sweep, the compression-against-efficiency scatter of a
//! survey), drawn to SVG text and PNG bytes, and captions on side-by-side
//! renders. Text uses DejaVu Sans, which the
//! `dejavu` crate embeds, so nothing depends on the fonts of the machine.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::FontStyle;

use acdf::error::{Error, Result};

/// The family name every figure asks for.
const FAMILY: &str = "sans-serif";

/// Register the embedded font once per process.
fn ensure_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, dejavu::sans::regular()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::Plot {
            path: "font".into(),
            message: "the embedded DejaVu Sans font did not load".into(),
        })
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// Points joined in order of x, each marked.
    Line,
    /// Points alone.
    Points,
}

/// One series of a panel: (x, y) points, both positive (others are left
/// out).
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
}

/// A single labelled point, drawn as a triangle (a reference sampler, a
/// point a search chose).
#[derive(Debug, Clone)]
pub struct Marker {
    pub label: String,
    pub point: (f64, f64),
}

/// One log-log panel: series, markers, and lines of text printed in its
/// upper left corner (for figures that would not fit the axes, e.g. a
/// sampler orders of magnitude below the others).
#[derive(Debug, Clone)]
pub struct Panel {
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub markers: Vec<Marker>,
    pub notes: Vec<String>,
    /// Whether to draw the legend in this panel.
    pub legend: bool,
}

/// Panels side by side under one title.
#[derive(Debug, Clone)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
}

fn plot_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Plot {
        path: path.to_path_buf(),
        message: e.to_string().replace('\n', " "),
    }
}

fn draw_figure<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    figure: &Figure,
) -> std::result::Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let inner = root
        .titled(&figure.title, (FAMILY, title_size(figure)))
        .map_err(|e| e.to_string())?;
    let areas = inner.split_evenly((1, figure.panels.len().max(1)));
    for (area, panel) in areas.into_iter().zip(&figure.panels) {
        draw_panel(area, panel)?;
    }
    root.present().map_err(|e| e.to_string())
}

/// The title's font size: 22 pixels, smaller where the title would not
/// fit the figure's width (a character is taken as 0.6 of the size).
fn title_size(figure: &Figure) -> u32 {
    let width = figure_size(figure).0 as f64;
    let chars = figure.title.chars().count().max(1) as f64;
    (width / (0.6 * chars)).floor().clamp(10.0, 22.0) as u32
}

/// Series colours: twelve hues that stay apart on white (the first ten
/// are the Tableau palette), then plotters' palette.
fn series_color(i: usize) -> RGBAColor {
    const COLORS: [RGBColor; 12] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(0, 0, 128),
        RGBColor(128, 128, 0),
    ];
    match COLORS.get(i) {
        Some(c) => c.to_rgba(),
        None => Palette99::pick(i).to_rgba(),
    }
}

/// The y range with headroom above the points for the legend of `entries`
/// lines (about 18 pixels each in a plotting area of about 460), so that
/// the legend, drawn in the upper right corner, covers no point.
fn with_legend_headroom(y: std::ops::Range<f64>, entries: usize) -> std::ops::Range<f64> {
    let share = ((entries as f64 * 18.0 + 24.0) / 460.0).min(0.8);
    let decades = (y.end / y.start).ln();
    y.start..(y.start.ln() + decades / (1.0 - share)).exp()
}

fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// The range of positive values, widened by a factor of 1.5 each way (a
/// decade around a single value; 1 to 10 for none).
fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|&v| positive(v))
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return 1.0..10.0;
    }
    if hi / lo < 1.5 {
        return lo / 3.0..hi * 3.0;
    }
    lo / 1.5..hi * 1.5
}

/// Tick labels of a log axis: plain numbers from 0.01 to 10^4, powers of
/// ten beyond.
fn tick(v: f64) -> String {
    if (1e-2..1e4).contains(&v.abs()) {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

fn draw_panel<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    plot: &Panel,
) -> std::result::Result<(), String>
where
    DB::ErrorType: 'static,
{
    let all = || {
        plot.series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .chain(plot.markers.iter().map(|m| m.point))
    };
    let x_range = log_range(all().map(|p| p.0));
    let mut y_range = log_range(all().map(|p| p.1));
    if plot.legend {
        y_range = with_legend_headroom(y_range, plot.series.len() + plot.markers.len());
    }

    let mut chart = ChartBuilder::on(&root)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range.log_scale(), y_range.clone().log_scale())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .x_labels(6)
        .y_labels(8)
        .label_style((FAMILY, 13))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .draw()
        .map_err(|e| e.to_string())?;

    for (i, s) in plot.series.iter().enumerate() {
        let color = series_color(i);
        let mut pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| positive(p.0) && positive(p.1))
            .collect();
        if s.style == Style::Line {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(|e| e.to_string())?;
        }
        let radius = if s.style == Style::Line { 3 } else { 2 };
        chart
            .draw_series(
                pts.into_iter()
                    .map(move |p| Circle::new(p, radius, color.filled())),
            )
            .map_err(|e| e.to_string())?
            .label(s.label.clone())
            .legend(move |(x, y)| Circle::new((x + 9, y), 4, color.filled()));
    }
    for (i, m) in plot.markers.iter().enumerate() {
        if !(positive(m.point.0) && positive(m.point.1)) {
            continue;
        }
        let shade = RGBColor(0, 0, 0).mix(1.0 - 0.35 * (i % 3) as f64);
        chart
            .draw_series(std::iter::once(TriangleMarker::new(
                m.point,
                8,
                shade.filled(),
            )))
            .map_err(|e| e.to_string())?
            .label(m.label.clone())
            .legend(move |(x, y)| TriangleMarker::new((x + 9, y), 6, shade.filled()));
    }
    for (k, note) in plot.notes.iter().enumerate() {
        chart
            .plotting_area()
            .draw(&Text::new(
                note.clone(),
                (
                    chart.plotting_area().get_x_range().start,
                    y_range.end / 1.25f64.powi(k as i32 + 1),
                ),
                (FAMILY, 13).into_font().color(&BLACK),
            ))
            .map_err(|e| e.to_string())?;
    }
    if plot.legend {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FAMILY, 13))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// The pixel size of a figure: 700 × 560 per panel.
fn figure_size(figure: &Figure) -> (u32, u32) {
    (700 * figure.panels.len().max(1) as u32, 560u32)
}

/// Draw the figure as SVG text and as PNG bytes, 700 × 560 pixels per
/// panel; `name` names the figure in errors. The caller writes them.
pub fn figure_bytes(figure: &Figure, name: &Path) -> Result<(String, Vec<u8>)> {
    ensure_font()?;
    let size = figure_size(figure);
    let mut svg = String::new();
    draw_figure(
        SVGBackend::with_string(&mut svg, size).into_drawing_area(),
        figure,
    )
    .map_err(|e| plot_error(name, e))?;
    let mut pixels = vec![0u8; size.0 as usize * size.1 as usize * 3];
    draw_figure(
        BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area(),
        figure,
    )
    .map_err(|e| plot_error(name, e))?;
    let image = image::RgbImage::from_raw(size.0, size.1, pixels)
        .ok_or_else(|| plot_error(name, "the bitmap has the wrong size"))?;
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| plot_error(name, e))?;
    Ok((svg, png))
}

/// Write an 8-bit RGB image as a PNG file, atomically
/// ([`acdf_io::fsio::write_atomic`]).
pub fn write_png(path: &Path, image: &image::RgbImage) -> Result<()> {
    use image::ImageEncoder;
    Ok(acdf_io::fsio::write_atomic(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(
                image.as_raw(),
                image.width(),
                image.height(),
                image::ExtendedColorType::Rgb8,
            )
            .map_err(std::io::Error::other)
    })?)
}

/// The figure as SVG text, 700 × 560 pixels per panel, for a caller that
/// writes the file itself.
pub fn figure_svg(figure: &Figure) -> Result<String> {
    ensure_font()?;
    let size = (700 * figure.panels.len().max(1) as u32, 560u32);
    let mut svg = String::new();
    draw_figure(
        SVGBackend::with_string(&mut svg, size).into_drawing_area(),
        figure,
    )
    .map_err(|e| plot_error(Path::new("svg"), e))?;
    Ok(svg)
}

/// How a tile's caption is set: its font size and lines.
struct Caption {
    size: f64,
    lines: Vec<String>,
}

/// The caption of a tile `width` pixels wide: the label on one line at the
/// largest size from 15 down to 9 pixels that fits the tile; where even 9
/// does not, the label broken after its hyphens and spaces into as few
/// lines as fit (a single word longer than the tile keeps a line of its
/// own). So labels
/// stay inside their tiles, and readable, at 64 pixels.
fn caption_for(label: &str, width: u32) -> Result<Caption> {
    let room = width.saturating_sub(4);
    let fits = |text: &str, size: f64| -> Result<bool> {
        let (w, _) = (FAMILY, size)
            .into_font()
            .box_size(text)
            .map_err(|e| plot_error(Path::new("side-by-side"), e))?;
        Ok(w <= room)
    };
    for size in (9..=15).rev().map(f64::from) {
        if fits(label, size)? {
            return Ok(Caption {
                size,
                lines: vec![label.to_string()],
            });
        }
    }
    let size = 9.0;
    let mut lines: Vec<String> = Vec::new();
    for word in label.split_inclusive(['-', ' ']) {
        match lines.last_mut() {
            Some(line) if fits(&format!("{line}{word}"), size)? => line.push_str(word),
            _ => lines.push(word.to_string()),
        }
    }
    Ok(Caption { size, lines })
}

/// The images side by side with their labels above them, on white: the
/// figure of a render's strategies. Each label is set at the largest size
/// from 15 down to 9 pixels that fits its tile, and broken into lines where
/// none does, so that labels stay inside their tiles at 64 pixels.
pub fn side_by_side(images: &[(String, image::RgbImage)]) -> Result<image::RgbImage> {
    ensure_font()?;
    const GAP: u32 = 4;
    let captions = images
        .iter()
        .map(|(label, img)| caption_for(label, img.width()))
        .collect::<Result<Vec<_>>>()?;
    let line_height = |c: &Caption| c.size.ceil() as u32 + 3;
    let caption_height = captions
        .iter()
        .map(|c| 4 + c.lines.len() as u32 * line_height(c))
        .max()
        .unwrap_or(0)
        .max(22);
    let width: u32 = images
        .iter()
        .map(|(_, i)| i.width() + GAP)
        .sum::<u32>()
        .saturating_sub(GAP);
    let height = images.iter().map(|(_, i)| i.height()).max().unwrap_or(0) + caption_height;
    let mut out =
        image::RgbImage::from_pixel(width.max(1), height.max(1), image::Rgb([255, 255, 255]));
    let mut x = 0u32;
    let mut origins = Vec::new();
    for (_, img) in images {
        image::imageops::replace(&mut out, img, x as i64, caption_height as i64);
        origins.push(x);
        x += img.width() + GAP;
    }
    let (w, h) = out.dimensions();
    {
        let root = BitMapBackend::with_buffer(&mut out, (w, h)).into_drawing_area();
        for (caption, x) in captions.iter().zip(origins) {
            for (k, line) in caption.lines.iter().enumerate() {
                root.draw(&Text::new(
                    line.clone(),
                    (x as i32 + 2, 3 + (k as u32 * line_height(caption)) as i32),
                    (FAMILY, caption.size).into_font().color(&BLACK),
                ))
                .map_err(|e| plot_error(Path::new("side-by-side"), e))?;
            }
        }
        root.present()
            .map_err(|e| plot_error(Path::new("side-by-side"), e))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At 64 pixels a tile's label stays over its tile: the gaps between
    /// tiles stay white, and the longest label is broken into lines.
    #[test]
    fn side_by_side_labels_stay_over_their_tiles() {
        let tile = image::RgbImage::from_pixel(64, 48, image::Rgb([40, 40, 40]));
        let labels = [
            "reference",
            "mis-one-sample-adaptive",
            "white: error 0.1134",
            "4 spp 0.0722",
        ];
        let images: Vec<(String, image::RgbImage)> = labels
            .iter()
            .map(|l| (l.to_string(), tile.clone()))
            .collect();
        let out = side_by_side(&images).unwrap();
        let caption_height = out.height() - 48;
        assert!(caption_height >= 22);
        assert_eq!(out.width(), 4 * 64 + 3 * 4);
        for k in 0..3u32 {
            let gap = k * 68 + 64..k * 68 + 68;
            for x in gap {
                for y in 0..out.height() {
                    let p = out.get_pixel(x, y).0;
                    assert!(p.iter().all(|&c| c > 200), "gap pixel ({x}, {y}) is {p:?}");
                }
            }
        }
        // Text was drawn over every tile's caption strip.
        for k in 0..4u32 {
            let dark = (k * 68..k * 68 + 64)
                .flat_map(|x| (0..caption_height).map(move |y| (x, y)))
                .filter(|&(x, y)| out.get_pixel(x, y).0[0] < 128)
                .count();
            assert!(dark > 20, "tile {k}: {dark} dark caption pixels");
        }
        let long = caption_for("mis-one-sample-adaptive", 64).unwrap();
        assert!(long.lines.len() >= 2, "{:?}", long.lines);
        assert_eq!(caption_for("brdf", 64).unwrap().size, 15.0);
    }

    #[test]
    fn figures_draw_to_svg_and_png() {
        let panel = Panel {
            x_label: "storage (bytes)".into(),
            y_label: "efficiency".into(),
            series: vec![
                Series {
                    label: "dp".into(),
                    points: vec![(1e3, 5.0), (1e4, 8.0), (1e5, 9.0), (-1.0, f64::NAN)],
                    style: Style::Line,
                },
                Series {
                    label: "scatter".into(),
                    points: vec![(2e3, 0.5)],
                    style: Style::Points,
                },
            ],
            markers: vec![Marker {
                label: "uniform".into(),
                point: (1e6, 10.0),
            }],
            notes: vec!["cosine (no tables): 3.1e-4".into()],
            legend: true,
        };
        let figure = Figure {
            title: "test".into(),
            panels: vec![
                panel.clone(),
                Panel {
                    legend: false,
                    ..panel
                },
            ],
        };
        let (svg, png) = figure_bytes(&figure, Path::new("test")).unwrap();
        for needle in [
            "storage (bytes)",
            "uniform",
            "cosine (no tables): 3.1e-4",
            "scatter",
        ] {
            assert!(svg.contains(needle), "{needle}");
        }
        let img = image::load_from_memory(&png).unwrap();
        assert_eq!((img.width(), img.height()), (1400, 560));
        assert_eq!(tick(0.25), "0.25");
        assert_eq!(tick(100.0), "100");
        assert_eq!(tick(1e-5), "1e-5");
    }

    /// The legend's headroom leaves the points below the share of the
    /// height the legend takes, and a long title is set smaller so that it
    /// fits.
    #[test]
    fn legend_headroom_and_long_titles() {
        let y = with_legend_headroom(1.0..100.0, 11);
        let legend_share = (11.0 * 18.0 + 24.0) / 460.0;
        let points_share = (100f64).ln() / (y.end / y.start).ln();
        assert!((points_share - (1.0 - legend_share)).abs() < 1e-9);
        assert_eq!(with_legend_headroom(1.0..10.0, 0).start, 1.0);
        let figure = |title: &str| Figure {
            title: title.into(),
            panels: Vec::new(),
        };
        assert_eq!(title_size(&figure("short")), 22);
        let long = "100 MERL materials: compression and efficiency against uniform@32x16x256x32";
        let size = title_size(&figure(long));
        assert!(size < 22 && 0.6 * size as f64 * long.chars().count() as f64 <= 700.0);
        assert_ne!(series_color(9), series_color(0));
    }

    #[test]
    fn side_by_side_stacks_widths() {
        let a = image::RgbImage::new(10, 8);
        let b = image::RgbImage::new(12, 9);
        let out = side_by_side(&[("a".into(), a), ("b".into(), b)]).unwrap();
        assert_eq!(out.dimensions(), (26, 9 + 22));
    }
}
