//! The source kinds reliefd knows, and how to open each. This is the one
//! place where source crates are plugged in.

use std::sync::Arc;

use relief_source::{PayloadKind, Source, SourceError, SourceSpec, TileGrid, VectorFormat, VectorSource};

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
    /// For a kind whose inputs' payloads depend on its options (scatter:
    /// the third input is a density raster or a point layer, as
    /// `points_input` says): the payload each declared input must have.
    /// None: `inputs`, by position.
    pub input_kinds: Option<fn(&SourceSpec) -> Vec<PayloadKind>>,
}

/// A file-backed vector kind: its format read through `VectorSource`,
/// reprojected by OSR; features out, or meshes for a MultiPatch layer (the
/// open source says so; `output` is what the graph assumes of one that
/// failed to open).
fn vector_kind<F: VectorFormat>() -> Kind {
    Kind {
        name: F::KIND,
        open: |spec, grid| {
            let crs = Arc::new(relief_source_gdal::OsrTransform);
            Ok(Arc::new(VectorSource::<F>::open(spec, grid, crs)?))
        },
        inputs: &[],
        required_inputs: 0,
        output: Some(PayloadKind::Features),
        input_kinds: None,
    }
}

impl Kind {
    /// The payload each of `spec.inputs` must have, in order (as many as
    /// the kind takes).
    pub fn expected_inputs(&self, spec: &SourceSpec) -> Vec<PayloadKind> {
        match self.input_kinds {
            Some(kinds) => kinds(spec),
            None => self.inputs.to_vec(),
        }
    }
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
                    input_kinds: None,
                },
                vector_kind::<relief_source_shapefile::Shapefile>(),
                vector_kind::<relief_source_kml::Kml>(),
                vector_kind::<relief_source_ogr::Ogr>(),
                Kind {
                    name: relief_source_ops::RASTERIZE_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Rasterize::open(spec)?)),
                    inputs: relief_source_ops::RASTERIZE_INPUTS,
                    required_inputs: relief_source_ops::RASTERIZE_INPUTS.len(),
                    output: Some(PayloadKind::Color),
                    input_kinds: None,
                },
                Kind {
                    name: relief_source_ops::OVERLAY_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Overlay::open(spec)?)),
                    inputs: relief_source_ops::OVERLAY_INPUTS,
                    required_inputs: relief_source_ops::OVERLAY_INPUTS.len(),
                    output: Some(PayloadKind::Color),
                    input_kinds: None,
                },
                Kind {
                    name: relief_source_ops::HILLSHADE_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Hillshade::open(spec)?)),
                    inputs: relief_source_ops::HILLSHADE_INPUTS,
                    required_inputs: relief_source_ops::HILLSHADE_INPUTS.len(),
                    output: Some(PayloadKind::Color),
                    input_kinds: None,
                },
                Kind {
                    name: relief_source_ops::EXTRUDE_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Extrude::open(spec)?)),
                    inputs: relief_source_ops::EXTRUDE_INPUTS,
                    required_inputs: 1,
                    output: Some(PayloadKind::Mesh),
                    input_kinds: None,
                },
                Kind {
                    name: relief_source_ops::INSTANCES_KIND,
                    open: |spec, _grid| Ok(Arc::new(relief_source_ops::Instances::open(spec)?)),
                    inputs: relief_source_ops::INSTANCES_INPUTS,
                    required_inputs: 1,
                    output: Some(PayloadKind::Instances),
                    input_kinds: None,
                },
                Kind {
                    name: relief_source_ops::SCATTER_KIND,
                    open: |spec, grid| Ok(Arc::new(relief_source_ops::Scatter::open(spec, grid)?)),
                    inputs: relief_source_ops::SCATTER_INPUTS,
                    required_inputs: 2,
                    output: Some(PayloadKind::Instances),
                    input_kinds: Some(relief_source_ops::scatter_input_kinds),
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

#[cfg(test)]
mod tests {
    use relief_source::OptionValue;

    use super::*;

    #[test]
    fn a_scatter_expects_its_inputs_as_its_options_say() -> Result<(), Box<dyn std::error::Error>> {
        let registry = Registry::builtin();
        let scatter = registry.get("scatter").ok_or("no scatter kind")?;
        let spec = |inputs: &[&str], options: &[(&str, &str)]| SourceSpec {
            id: "forest".into(),
            kind: "scatter".into(),
            inputs: inputs.iter().map(|s| (*s).to_owned()).collect(),
            options: options.iter().map(|(k, v)| ((*k).to_owned(), OptionValue::Text((*v).to_owned()))).collect(),
            ..SourceSpec::default()
        };
        use PayloadKind::{Features, Height};
        assert_eq!(
            scatter.expected_inputs(&spec(&["c", "g", "p"], &[("points_input", "p")])),
            [Height, Height, Features]
        );
        assert_eq!(scatter.expected_inputs(&spec(&["c", "g", "d", "p"], &[])), [Height, Height, Height, Features]);
        // Other kinds: by position.
        let extrude = registry.get("extrude").ok_or("no extrude kind")?;
        assert_eq!(extrude.expected_inputs(&spec(&["f"], &[])), [Features, Height]);
        Ok(())
    }

    #[test]
    fn a_scene_may_give_a_scatter_points_without_a_density_raster() -> Result<(), Box<dyn std::error::Error>> {
        let scene = |extra: &str| {
            let text = format!(
                r#"
                [scene]
                name = "forest"
                [[source]]
                id = "landcover"
                kind = "gdal"
                path = "missing-landcover.tif"
                [[source]]
                id = "dem"
                kind = "gdal"
                path = "missing-dem.tif"
                [[source]]
                id = "trees"
                kind = "shapefile"
                path = "missing-trees.shp"
                [[source]]
                id = "forest"
                kind = "scatter"
                inputs = ["landcover", "dem", "trees"]
                {extra}
                [[source.rule]]
                class = 311
                models = {{ conifer = 0.7, broadleaf = 0.3 }}
                density = 21000
                "#
            );
            let manifest = crate::manifest::Manifest::parse(&text, std::path::Path::new("/nowhere/scene.toml"))
                .map_err(|e| vec![crate::graph::LoadError::from(e)])?;
            crate::graph::build(manifest, &Registry::builtin(), None)
        };
        // The files are missing (those sources fail to open), but the graph
        // is checked: points named as such are features.
        let (snapshot, _open_errors) = scene("points_input = \"trees\"").map_err(|e| format!("{e:?}"))?;
        let forest = snapshot.slots.iter().find(|s| s.spec.id == "forest").ok_or("no forest slot")?;
        assert!(forest.source.is_some(), "{:?}", forest.error);
        // Taken by position, the third input is a density raster.
        let errors = scene("").unwrap_err();
        let text: Vec<String> = errors.iter().map(ToString::to_string).collect();
        assert!(
            text.iter().any(|e| e.contains("source 'forest', field 'inputs[2]'") && e.contains("needs height")),
            "{text:?}"
        );
        Ok(())
    }
}
