//! A file geodatabase (an ArcGIS `.gdb` folder) as files: which hold a
//! layer, whether it is MultiPatch, and what ArcGIS's locks on it say.
//!
//! Each table is a set of files named by its number in the system catalog
//! (`GDB_SystemCatalog`, itself table 1): `a0000000b.gdbtable` (rows),
//! `.gdbtablx` (row offsets), `.gdbindexes`, `.spx`, `.atx`, `.freelist`.
//! A layer's data is its table's files, and the catalog that names it: those
//! are what a read depends on, so what is stamped and watched. ArcGIS writes
//! lock files beside them: `<table or _gdb>.<host>.<pid>.<n>.<kind>.lock`.

use std::path::{Path, PathBuf};

use gdal::vector::LayerAccess;
use gdal::{Dataset, DatasetOptions, GdalOpenFlags};
use relief_source::SourceError;
use relief_source::files::write_lock_holds;

/// The catalog's own table.
const CATALOG: &str = "a00000001.gdbtable";

pub(crate) fn is_gdb(path: &Path) -> bool {
    path.is_dir() && path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("gdb"))
}

/// The table file of the layer named `layer` (or of the only user table),
/// and the catalog's: the files whose datasets a read of it depends on.
/// With no such layer (or several and none named), the catalog alone: the
/// read says what is wrong.
pub(crate) fn stamped(path: &Path, layer: Option<&str>) -> Result<Vec<PathBuf>, SourceError> {
    let mut files = vec![path.join(CATALOG)];
    if let Some(table) = table_number(path, layer)? {
        files.insert(0, path.join(table_file(table)));
    }
    Ok(files)
}

fn table_file(table: u64) -> String {
    format!("a{table:08x}.gdbtable")
}

/// The layer's table number, from GDAL's reading of the catalog.
fn table_number(path: &Path, layer: Option<&str>) -> Result<Option<u64>, SourceError> {
    relief_source_gdal::configure_gdal();
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_VECTOR | GdalOpenFlags::GDAL_OF_READONLY,
        allowed_drivers: Some(&["OpenFileGDB"]),
        open_options: Some(&["LIST_ALL_TABLES=YES"]),
        ..DatasetOptions::default()
    };
    let ds = Dataset::open_ex(path, options).map_err(|e| {
        SourceError::format(
            format!(
                "cannot read the geodatabase's catalog: {}",
                relief_source_gdal::gdal_message(e, path, "not a file geodatabase").trim_end_matches('.')
            ),
            path,
        )
    })?;
    let mut catalog = ds
        .layer_by_name("GDB_SystemCatalog")
        .map_err(|_| SourceError::format("the geodatabase has no system catalog (GDB_SystemCatalog)", path))?;
    let name = catalog
        .defn()
        .field_index("Name")
        .map_err(|_| SourceError::format("the geodatabase's system catalog has no Name field", path))?;
    let tables: Vec<(u64, String)> =
        catalog.features().filter_map(|f| Some((f.fid()?, f.field_as_string(name).ok().flatten()?))).collect();
    let user: Vec<&(u64, String)> = tables.iter().filter(|(_, name)| !name.starts_with("GDB_")).collect();
    Ok(match layer {
        Some(wanted) => tables.iter().find(|(_, name)| name.eq_ignore_ascii_case(wanted)).map(|(n, _)| *n),
        None => match user.as_slice() {
            [(n, _)] => Some(*n),
            _ => None,
        },
    })
}

/// True when ArcGIS's layer definition says MultiPatch.
pub(crate) fn is_multipatch(ds: &Dataset, layer: &str) -> bool {
    let query = format!("GetLayerDefinition {layer}");
    let Ok(Some(mut rows)) = ds.execute_sql(query, None, gdal::vector::sql::Dialect::DEFAULT) else {
        return false;
    };
    rows.features()
        .filter_map(|f| f.field_as_string(0).ok().flatten())
        .any(|xml| xml.contains("<ShapeType>esriGeometryMultiPatch</ShapeType>"))
}

/// ArcGIS's edit and write locks on `table` (a `.gdbtable` in a `.gdb`)
/// or on the whole geodatabase, by name.
pub(crate) fn write_locks(table: &Path) -> Vec<String> {
    let (Some(dir), Some(stem)) = (table.parent(), table.file_stem().and_then(|s| s.to_str())) else {
        return Vec::new();
    };
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut locks: Vec<String> = entries
        .flatten()
        .filter_map(|e| e.file_name().to_str().map(str::to_owned))
        .filter(|name| write_lock_holds(Path::new(name), |s| s.eq_ignore_ascii_case(stem)))
        .collect();
    locks.sort();
    locks
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_are_named_by_their_catalog_number() {
        assert_eq!(table_file(11), "a0000000b.gdbtable");
    }

    #[test]
    fn locks_are_found_by_table_or_whole_database() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let table = dir.path().join("a0000000b.gdbtable");
        for name in [
            "a0000000b.gdbtable",
            "a0000000b.HOST.1.2.sr.lock",
            "a0000000b.HOST.1.2.ed.lock",
            "a0000000c.HOST.1.2.ed.lock",
            "_gdb.HOST.1.2.wr.lock",
        ] {
            std::fs::write(dir.path().join(name), b"")?;
        }
        assert_eq!(write_locks(&table), vec!["_gdb.HOST.1.2.wr.lock", "a0000000b.HOST.1.2.ed.lock"]);
        Ok(())
    }
}
