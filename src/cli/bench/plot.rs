//! The sweep's plot: RMSE against wall time, both logarithmic, one line
//! per sampling pattern and area-light model.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::FontStyle;

use super::CliError;
use super::sweep::Row;
use crate::render::output::write_rgb8;
use crate::render::{AreaLightModel, Sampling};

const SIZE: (u32, u32) = (1100, 760);
const FONT: &str = "sans-serif";

/// Colours by pattern (index in `Sampling::ALL`, cycling for new ones).
const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

/// plotters' ab_glyph backend draws only registered fonts; egui's bundled
/// Ubuntu-Light (compiled in with the viewer) saves shipping a font file.
fn register_font() -> Result<(), CliError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        let mut defs = egui::FontDefinitions::default();
        let Some(data) = defs
            .font_data
            .remove("Ubuntu-Light")
            .or_else(|| defs.font_data.pop_first().map(|(_, d)| d))
        else {
            return false;
        };
        // The bytes are static inside egui; leaking the small handle gives
        // them the 'static lifetime plotters wants, without a copy.
        let data: &'static egui::FontData = Box::leak(Box::new((*data).clone()));
        plotters::style::register_font(FONT, FontStyle::Normal, data.bytes()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(CliError::other("plot: no usable font"))
    }
}

fn index_of<T: PartialEq>(all: &[T], x: &T) -> usize {
    all.iter().position(|a| a == x).unwrap_or(0)
}

/// Writes the plot of `rows` as a PNG.
pub fn plot(path: &Path, title: &str, rows: &[Row]) -> Result<(), CliError> {
    register_font()?;
    let fail = |e: &dyn std::fmt::Display| CliError::other(format!("plot: {e}"));
    // Log axes cannot show a zero error or time.
    let points: Vec<&Row> = rows
        .iter()
        .filter(|r| r.rmse > 0.0 && r.rmse.is_finite() && r.time_s > 0.0)
        .collect();
    if points.is_empty() {
        return Err(CliError::other(
            "plot: no configuration with a time and an error > 0",
        ));
    }
    let fold = |f: fn(&Row) -> f64| {
        points
            .iter()
            .map(|r| f(r))
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (t0, t1) = fold(|r| r.time_s);
    let (e0, e1) = fold(|r| r.rmse);
    let x_range = (t0 / 1.5)..(t1 * 1.5);
    let y_range = (e0 / 1.5)..(e1 * 1.5);

    let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT, 24))
            .margin(18)
            .x_label_area_size(56)
            .y_label_area_size(84)
            .build_cartesian_2d(x_range.log_scale(), y_range.log_scale())
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("wall time per image, s (median)")
            .y_desc("RMSE against the converged reference (linear RGB)")
            .x_label_formatter(&|x| format_tick(*x))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .label_style((FONT, 16))
            .axis_desc_style((FONT, 18))
            .draw()
            .map_err(|e| fail(&e))?;
        let mut series: Vec<(Sampling, AreaLightModel)> = Vec::new();
        for r in &points {
            if !series.contains(&(r.sampling, r.model)) {
                series.push((r.sampling, r.model));
            }
        }
        for (sampling, model) in series {
            // Joined in the order swept (growing ray count), so that noisy
            // times show as kinks rather than scrambling the line.
            let line: Vec<(f64, f64)> = points
                .iter()
                .filter(|r| r.sampling == sampling && r.model == model)
                .map(|r| (r.time_s, r.rmse))
                .collect();
            let colour = COLOURS[index_of(&Sampling::ALL, &sampling) % COLOURS.len()];
            let model_index = index_of(&AreaLightModel::ALL, &model);
            let style = colour.stroke_width(2);
            let label = format!("{} / {}", sampling.name(), model.name());
            // Solid for the first model, dashed for the others.
            if model_index == 0 {
                chart
                    .draw_series(LineSeries::new(line.clone(), style))
                    .map_err(|e| fail(&e))?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
            } else {
                let dash = (10 / model_index as u32).max(2);
                chart
                    .draw_series(DashedLineSeries::new(line.clone(), dash, 6, style))
                    .map_err(|e| fail(&e))?
                    .label(label)
                    .legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (9, 0)], style)
                            + PathElement::new(vec![(15, 0), (24, 0)], style)
                    });
            }
            chart
                .draw_series(line.iter().map(|&p| {
                    // Filled markers for the first model, hollow for others.
                    let marker = if model_index == 0 {
                        colour.filled()
                    } else {
                        colour.stroke_width(2)
                    };
                    Circle::new(p, 4, marker)
                }))
                .map_err(|e| fail(&e))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT, 16))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| fail(&e))?;
        root.present().map_err(|e| fail(&e))?;
    }
    write_rgb8(path, SIZE.0, SIZE.1, &buf).map_err(CliError::other)
}

/// Tick labels of the time axis: short and without trailing noise.
fn format_tick(x: f64) -> String {
    if x >= 1.0 {
        format!("{x:.1}")
    } else if x >= 0.01 {
        format!("{x:.2}")
    } else {
        format!("{x:.0e}")
    }
}
