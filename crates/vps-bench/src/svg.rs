//! The SVG writer the plotting commands share (`vps sweep --plots`, `vps bench scaling --plot`):
//! a white canvas drawn in memory, then written atomically, so that a failed draw or write leaves
//! no truncated plot. Not a subcommand.

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Draws a `size` (pixels, width × height) white canvas with `draw`, then writes it to `path`
/// atomically (a temporary file in the same directory, renamed into place). Errors name the path.
pub fn write_svg<F>(path: &Path, size: (u32, u32), draw: F) -> Result<()>
where
    F: FnOnce(&DrawingArea<SVGBackend, Shift>) -> Result<()>,
{
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE)?;
        draw(&root)?;
        root.present()?;
    }
    vps_app::output::write_file(path, svg.as_bytes())
}

/// Draws the series' legend as the plots share it: a white box, 80 % opaque, with a black border.
pub fn draw_legend<'a, X: Ranged, Y: Ranged>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<X, Y>>,
) -> Result<()> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
