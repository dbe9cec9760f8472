//! Figures: the efficiency- and variance-against-storage plots of a sweep
//! (SVG and PNG) and
//! captions on side-by-side renders. Text uses DejaVu Sans, which the
//! `dejavu` crate embeds, so nothing depends on the fonts of the machine.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::error::{Error, Result};

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

/// One line of the plot: (storage in bytes, efficiency) points.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

/// One panel of a sweep figure, a quantity against storage: the simplifier
/// curves, the uniform sampler as one marked point and the cosine sampler
/// (no storage) as a horizontal line.
#[derive(Debug, Clone)]
pub struct Panel {
    /// The quantity on the (logarithmic) y axis.
    pub y_label: String,
    pub series: Vec<Series>,
    /// (storage bytes, value) of the uniform tabulation.
    pub uniform: (f64, f64),
    /// The value of cosine sampling.
    pub cosine: f64,
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
        .titled(&figure.title, (FAMILY, 22))
        .map_err(|e| e.to_string())?;
    let areas = inner.split_evenly((1, figure.panels.len().max(1)));
    for (area, panel) in areas.into_iter().zip(&figure.panels) {
        draw_panel(area, panel)?;
    }
    root.present().map_err(|e| e.to_string())
}

fn draw_panel<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    plot: &Panel,
) -> std::result::Result<(), String>
where
    DB::ErrorType: 'static,
{
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let xs = plot
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .chain(std::iter::once(plot.uniform.0))
        .filter(|&v| positive(v));
    let ys = plot
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .chain([plot.uniform.1, plot.cosine])
        .filter(|&v| positive(v));
    let (xmin, xmax) = xs.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (ymin, ymax) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (xmin, xmax) = if xmin.is_finite() {
        (xmin / 2.0, xmax * 2.0)
    } else {
        (1.0, 10.0)
    };
    let (ymin, ymax) = if ymin.is_finite() {
        (ymin / 2.0, ymax * 2.0)
    } else {
        (1.0, 10.0)
    };

    let mut chart = ChartBuilder::on(&root)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((xmin..xmax).log_scale(), (ymin..ymax).log_scale())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("storage (bytes)")
        .y_desc(plot.y_label.as_str())
        .x_labels(6)
        .y_labels(8)
        .label_style((FAMILY, 13))
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| e.to_string())?;

    let palette = [&BLUE, &RED, &GREEN, &MAGENTA, &CYAN];
    for (i, s) in plot.series.iter().enumerate() {
        let color = palette[i % palette.len()];
        let mut pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| positive(p.0) && positive(p.1))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        chart
            .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))
            .map_err(|e| e.to_string())?;
    }
    if positive(plot.uniform.0) && positive(plot.uniform.1) {
        chart
            .draw_series(std::iter::once(TriangleMarker::new(
                plot.uniform,
                8,
                BLACK.filled(),
            )))
            .map_err(|e| e.to_string())?
            .label("uniform")
            .legend(|(x, y)| TriangleMarker::new((x + 9, y), 6, BLACK.filled()));
    }
    if positive(plot.cosine) {
        let c = plot.cosine;
        chart
            .draw_series(LineSeries::new(
                vec![(xmin, c), (xmax, c)],
                BLACK.mix(0.6).stroke_width(1),
            ))
            .map_err(|e| e.to_string())?
            .label("cosine (no storage)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.mix(0.6)));
    }
    if plot.legend {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FAMILY, 13))
            .position(SeriesLabelPosition::LowerRight)
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Draw the figure as an SVG file and as a PNG file, 700 × 560 pixels per
/// panel.
pub fn plot_figure(figure: &Figure, svg: &Path, png: &Path) -> Result<()> {
    ensure_font()?;
    let size = (700 * figure.panels.len().max(1) as u32, 560u32);
    draw_figure(SVGBackend::new(svg, size).into_drawing_area(), figure)
        .map_err(|e| plot_error(svg, e))?;
    draw_figure(BitMapBackend::new(png, size).into_drawing_area(), figure)
        .map_err(|e| plot_error(png, e))?;
    Ok(())
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

/// Put images side by side, left to right, with a caption strip above each.
pub fn side_by_side(images: &[(String, image::RgbImage)]) -> Result<image::RgbImage> {
    ensure_font()?;
    const CAPTION: u32 = 22;
    const GAP: u32 = 4;
    let width: u32 = images
        .iter()
        .map(|(_, i)| i.width() + GAP)
        .sum::<u32>()
        .saturating_sub(GAP);
    let height = images.iter().map(|(_, i)| i.height()).max().unwrap_or(0) + CAPTION;
    let mut out =
        image::RgbImage::from_pixel(width.max(1), height.max(1), image::Rgb([255, 255, 255]));
    let mut x = 0u32;
    let mut captions = Vec::new();
    for (label, img) in images {
        image::imageops::replace(&mut out, img, x as i64, CAPTION as i64);
        captions.push((label.clone(), x));
        x += img.width() + GAP;
    }
    let (w, h) = out.dimensions();
    {
        let root = BitMapBackend::with_buffer(&mut out, (w, h)).into_drawing_area();
        for (label, x) in captions {
            root.draw(&Text::new(
                label,
                (x as i32 + 4, 3),
                (FAMILY, 15).into_font().color(&BLACK),
            ))
            .map_err(|e| plot_error(Path::new("side-by-side"), e))?;
        }
        root.present()
            .map_err(|e| plot_error(Path::new("side-by-side"), e))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plot_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let panel = Panel {
            y_label: "efficiency".into(),
            series: vec![Series {
                label: "dp".into(),
                points: vec![(1e3, 5.0), (1e4, 8.0), (1e5, 9.0)],
            }],
            uniform: (1e6, 10.0),
            cosine: 2.0,
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
        let (svg, png) = (dir.path().join("a.svg"), dir.path().join("a.png"));
        plot_figure(&figure, &svg, &png).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("storage (bytes)") && text.contains("uniform"));
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (1400, 560));
    }

    #[test]
    fn side_by_side_stacks_widths() {
        let a = image::RgbImage::new(10, 8);
        let b = image::RgbImage::new(12, 9);
        let out = side_by_side(&[("a".into(), a), ("b".into(), b)]).unwrap();
        assert_eq!(out.dimensions(), (26, 9 + 22));
    }
}
