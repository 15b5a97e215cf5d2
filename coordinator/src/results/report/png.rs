//! The report's SVG pictures as PNG (resvg), text set in the system's fonts.

use resvg::{tiny_skia, usvg};
use std::sync::Arc;

/// The system's fonts, loaded once per report (empty where a machine has none).
pub fn fonts() -> Arc<usvg::fontdb::Database> {
    let mut db = usvg::fontdb::Database::new();
    db.load_system_fonts();
    db.set_sans_serif_family("DejaVu Sans");
    Arc::new(db)
}

/// Renders an SVG document at its own size.
pub fn render(svg: &str, fonts: &Arc<usvg::fontdb::Database>) -> anyhow::Result<Vec<u8>> {
    let options = usvg::Options {
        fontdb: fonts.clone(),
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(svg, &options)?;
    let size = tree.size().to_int_size();
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or_else(|| anyhow::anyhow!("a picture of {size:?} cannot be rendered"))?;
    resvg::render(&tree, tiny_skia::Transform::default(), &mut pixmap.as_mut());
    Ok(pixmap.encode_png()?)
}
