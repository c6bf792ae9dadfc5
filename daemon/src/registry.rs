//! The source kinds reliefd knows, and how to open each. This is the one
//! place where source crates are plugged in.

use std::sync::Arc;

use relief_source::{PayloadKind, Source, SourceError, SourceSpec, TileGrid};

type OpenFn = fn(&SourceSpec, &TileGrid) -> Result<Arc<dyn Source>, SourceError>;

pub struct Kind {
    pub name: &'static str,
    pub open: OpenFn,
    /// The payloads of the inputs, in order; empty for file-backed sources.
    pub inputs: &'static [PayloadKind],
    /// How many of `inputs` must be given; the rest are optional.
    pub required_inputs: usize,
    /// The output payload when it is known without opening the source.
    pub output: Option<PayloadKind>,
}

pub struct Registry {
    kinds: Vec<Kind>,
}

impl Registry {
    /// Every kind built into this reliefd.
    pub fn builtin() -> Self {
        Self {
            kinds: vec![
                Kind {
                    name: relief_source_gdal::KIND,
                    open: |spec, grid| Ok(Arc::new(relief_source_gdal::GdalSource::open(spec, grid)?)),
                    inputs: &[],
                    required_inputs: 0,
                    output: None,
                },
                Kind {
                    name: relief_source_shapefile::KIND,
                    open: |spec, grid| {
                        let crs = Arc::new(relief_source_gdal::OsrTransform);
                        Ok(Arc::new(relief_source_shapefile::ShapefileSource::open(spec, grid, crs)?))
                    },
                    inputs: &[],
                    required_inputs: 0,
                    output: Some(PayloadKind::Features),
                },
                Kind {
                    name: relief_source_kml::KIND,
                    open: |spec, grid| {
                        let crs = Arc::new(relief_source_gdal::OsrTransform);
                        Ok(Arc::new(relief_source_kml::KmlSource::open(spec, grid, crs)?))
                    },
                    inputs: &[],
                    required_inputs: 0,
                    output: Some(PayloadKind::Features),
                },
                Kind {
                    name: relief_source_ops::RASTERIZE_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Rasterize::open(spec)?)),
                    inputs: relief_source_ops::RASTERIZE_INPUTS,
                    required_inputs: relief_source_ops::RASTERIZE_INPUTS.len(),
                    output: Some(PayloadKind::Color),
                },
                Kind {
                    name: relief_source_ops::OVERLAY_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Overlay::open(spec)?)),
                    inputs: relief_source_ops::OVERLAY_INPUTS,
                    required_inputs: relief_source_ops::OVERLAY_INPUTS.len(),
                    output: Some(PayloadKind::Color),
                },
                Kind {
                    name: relief_source_ops::HILLSHADE_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Hillshade::open(spec)?)),
                    inputs: relief_source_ops::HILLSHADE_INPUTS,
                    required_inputs: relief_source_ops::HILLSHADE_INPUTS.len(),
                    output: Some(PayloadKind::Color),
                },
                Kind {
                    name: relief_source_ops::EXTRUDE_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Extrude::open(spec)?)),
                    inputs: relief_source_ops::EXTRUDE_INPUTS,
                    required_inputs: 1,
                    output: Some(PayloadKind::Mesh),
                },
                Kind {
                    name: relief_source_ops::INSTANCES_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Instances::open(spec)?)),
                    inputs: relief_source_ops::INSTANCES_INPUTS,
                    required_inputs: 1,
                    output: Some(PayloadKind::Instances),
                },
            ],
        }
    }

    pub fn get(&self, name: &str) -> Option<&Kind> {
        self.kinds.iter().find(|k| k.name == name)
    }

    pub fn names(&self) -> Vec<&'static str> {
        self.kinds.iter().map(|k| k.name).collect()
    }
}
