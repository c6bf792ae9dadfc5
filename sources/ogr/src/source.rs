//! The `ogr` format: options, opening, layer choice, CRS and details.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use gdal::spatial_ref::SpatialRef;
use gdal::vector::LayerAccess;
use gdal::{Dataset, DatasetCapability, DatasetOptions, GdalOpenFlags};
use relief_source::{SourceError, SourceSpec, VectorFormat, VectorRead, VectorSource};
use relief_source_gdal::describe_srs;

use crate::gdb;
use crate::read::read_layer;

pub const KIND: &str = "ogr";

/// Drivers whose FIDs survive edits (a primary key in a database file);
/// for the others the read order is the id.
const STABLE_FID_DRIVERS: &[&str] = &["GPKG", "SQLite", "OpenFileGDB", "FileGDB"];

#[derive(Debug)]
pub struct Ogr;

/// One layer of an OGR vector dataset as a source.
pub type OgrSource = VectorSource<Ogr>;

/// GDAL's message for a failed call on `path`, without its final full stop.
fn gdal_message(e: gdal::errors::GdalError, path: &Path) -> String {
    relief_source_gdal::gdal_message(e, path, "no GDAL vector driver recognises it").trim_end_matches('.').to_owned()
}

/// A failed GDAL call on the dataset: the lock another program holds, or
/// GDAL's words after `what` and the layer.
fn failure(e: gdal::errors::GdalError, path: &Path, layer: Option<&str>, what: &str) -> SourceError {
    let message = gdal_message(e, path);
    if message.contains("database is locked") || message.contains("database is busy") {
        SourceError::Locked {
            message: format!(
                "the database is locked by another program (a write under way){}; the last good version stays \
                 and it is read again when the lock is gone",
                which(layer)
            ),
            path: path.to_path_buf(),
        }
    } else {
        SourceError::format(format!("{what}{}: {message}", which(layer)), path)
    }
}

/// " layer 'name'" when the manifest names one: errors say which layer.
fn which(layer: Option<&str>) -> String {
    layer.map(|l| format!(" (layer '{l}')")).unwrap_or_default()
}

fn open(path: &Path, layer: Option<&str>) -> Result<Dataset, SourceError> {
    let object = relief_source::objects::is_object(path);
    // GDAL opens it, and the side files it looks for, itself: a pipe in
    // their place would block it for good. A folder is a dataset too.
    if !object {
        relief_source::regular::check_for_gdal(path, true).map_err(|e| SourceError::Format {
            path: path.to_path_buf(),
            message: format!("cannot open{}: {e}", which(layer)),
        })?;
    }
    relief_source_gdal::configure_gdal();
    relief_source_gdal::guard::check_dataset(path).map_err(|e| SourceError::Format {
        path: path.to_path_buf(),
        message: format!("cannot open{}: {e}", which(layer)),
    })?;
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_VECTOR
            | GdalOpenFlags::GDAL_OF_READONLY
            | GdalOpenFlags::GDAL_OF_VERBOSE_ERROR,
        ..DatasetOptions::default()
    };
    // An object is opened without listing its "folder"; a zip of a
    // shapefile (or of any vector files) is read inside the object.
    let _empty_folder = object.then(relief_source_gdal::objects::EmptyFolder::set);
    let zipped = object && path.extension().is_some_and(|e| e.eq_ignore_ascii_case("zip"));
    let opened = if zipped { PathBuf::from(format!("/vsizip/{}", path.display())) } else { path.to_path_buf() };
    Dataset::open_ex(&opened, options).map_err(|e| failure(e, path, layer, "not a vector dataset GDAL can read"))
}

impl VectorFormat for Ogr {
    const KIND: &'static str = KIND;

    fn read(spec: &SourceSpec, path: &Path, stamped: &[PathBuf]) -> Result<VectorRead, SourceError> {
        spec.only_options(&[&["layer", "crs"], relief_source::patches::OPTIONS].concat())?;
        let wanted = spec.text("layer")?;
        let crs_option = spec.text("crs")?;
        let mut ds = open(path, wanted)?;
        if ds.has_capability(DatasetCapability::TRANSACTIONS) {
            // A database (GeoPackage, SQLite): everything below in one read
            // transaction, so it is one committed state whatever commits
            // meanwhile. Nothing is written; dropping it rolls nothing back.
            let snapshot =
                ds.start_transaction().map_err(|e| failure(e, path, wanted, "cannot start a read transaction"))?;
            read_dataset(&snapshot, wanted, crs_option, path, stamped)
        } else {
            read_dataset(&ds, wanted, crs_option, path, stamped)
        }
    }

    /// A file geodatabase's layer depends on its table's files and the
    /// catalog, not on the folder; any other dataset on its own files.
    fn stamped(spec: &SourceSpec, path: &Path) -> Result<Vec<PathBuf>, SourceError> {
        if gdb::is_gdb(path) { gdb::stamped(path, spec.text("layer")?) } else { Ok(vec![path.to_path_buf()]) }
    }
}

/// True when the `.shp` at `path` says MultiPatch in its header (OGR reads
/// its patches as plain polygons).
fn is_multipatch_shp(path: &Path) -> bool {
    use std::io::Read;
    let mut header = [0u8; 36];
    relief_source::regular::open_regular(path).and_then(|mut f| f.read_exact(&mut header)).is_ok()
        && i32::from_le_bytes([header[32], header[33], header[34], header[35]]) == 31
}

/// The chosen layer of an open dataset, read whole.
fn read_dataset(
    ds: &Dataset,
    wanted: Option<&str>,
    crs_option: Option<&str>,
    path: &Path,
    stamped: &[PathBuf],
) -> Result<VectorRead, SourceError> {
    let driver = ds.driver().short_name();
    let names: Vec<String> = ds.layers().map(|l| l.name()).collect();
    let mut layer = match (wanted, names.as_slice()) {
        (_, []) => return Err(SourceError::format("the dataset has no layers", path)),
        (Some(name), _) => ds
            .layer_by_name(name)
            .map_err(|_| SourceError::format(format!("no layer '{name}' (layers: {})", names.join(", ")), path))?,
        (None, [_]) => ds.layer(0).map_err(|e| SourceError::format(gdal_message(e, path), path))?,
        (None, _) => {
            return Err(SourceError::format(
                format!(
                    "the dataset has {} layers ({}): choose one with option 'layer'",
                    names.len(),
                    names.join(", ")
                ),
                path,
            ));
        }
    };
    let stable_fids = STABLE_FID_DRIVERS.contains(&driver.as_str());
    let geodatabase = gdb::is_gdb(path);
    // A geodatabase layer's files, as `stamped` found them: its table's
    // (named in errors) and the catalog's.
    let table = stamped.first().filter(|t| geodatabase && stamped.len() > 1 && t.exists());
    let read = read_layer(&mut layer, stable_fids, table.map_or(path, PathBuf::as_path))?;
    let surfaces = read.surfaces
        || (geodatabase && gdb::is_multipatch(ds, &layer.name()))
        || (driver == "ESRI Shapefile" && is_multipatch_shp(path));

    let layer_srs = layer.spatial_ref();
    let (crs, crs_name, crs_note) = match (crs_option, &layer_srs) {
        (Some(c), _) => {
            let name =
                SpatialRef::from_definition(c).map_or_else(|_| c.chars().take(80).collect(), |s| describe_srs(&s));
            (c.to_owned(), name, "from the manifest".to_owned())
        }
        (None, Some(srs)) => {
            let wkt = srs.to_wkt().map_err(|e| SourceError::Crs {
                crs: describe_srs(srs),
                message: format!("cannot write the layer's CRS as WKT: {}", gdal_message(e, path)),
                path: Some(path.to_path_buf()),
            })?;
            (wkt, describe_srs(srs), "from the layer".to_owned())
        }
        (None, None) => (
            "EPSG:4326".to_owned(),
            "EPSG:4326 (WGS 84, assumed)".to_owned(),
            "the layer has no CRS: WGS84 longitude/latitude assumed".to_owned(),
        ),
    };

    let mut details = BTreeMap::new();
    details.insert("driver".into(), driver);
    details.insert("layer".into(), layer.name());
    details.insert("layers".into(), names.join(", "));
    details.insert("features".into(), read.features.len().to_string());
    details.insert("null_geometries".into(), read.null_geometries.to_string());
    for (reason, count) in &read.skipped {
        details.insert(format!("skipped.{reason}"), count.to_string());
    }
    details.insert("fields".into(), read.fields.join(", "));
    details.insert("ids".into(), if stable_fids { "OGR FIDs" } else { "read order" }.into());
    details.insert("crs_source".into(), crs_note);
    let mut files = relief_source::files::dataset_files(path);
    let mut warnings = Vec::new();
    if geodatabase {
        if let Some(table) = table {
            details.insert(
                "table".into(),
                table.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
            );
            let locks = gdb::write_locks(table);
            if !locks.is_empty() {
                warnings.push(format!(
                    "read while ArcGIS's lock {} is on table '{}': an edit may be under way, or a crashed \
                     ArcGIS left it (relief waits [watch] write_timeout_ms for a lock to go, then reads); \
                     delete the lock file if no ArcGIS has the geodatabase open",
                    locks.join(", "),
                    layer.name()
                ));
            }
        }
        files.extend(stamped.iter().flat_map(|t| relief_source::files::dataset_files(t)));
    }
    Ok(VectorRead {
        features: read.features,
        crs,
        crs_name,
        crs_file: Some(path.to_path_buf()),
        files,
        vertical_datum: String::new(),
        details,
        warnings,
        surfaces,
    })
}
