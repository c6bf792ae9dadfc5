//! relief numbers tile rows from the north; quantized-mesh's `tms` scheme
//! from the south. Levels and columns are the same: relief's geodetic grid
//! is Cesium's geographic tiling scheme (EPSG:4326, 2 x 1 tiles at level 0).

use relief_source::{TileGrid, TileKey};

/// The TMS (level, x, y-from-the-south) address of a relief tile key.
pub fn tms_from_key(grid: &TileGrid, key: TileKey) -> (u8, u32, u32) {
    let (_, rows) = grid.tiles_at(key.level);
    (key.level, key.x, rows - 1 - key.y)
}

/// The relief tile key of a TMS address, or `None` outside the grid.
pub fn key_from_tms(grid: &TileGrid, level: u8, x: u32, tms_y: u32) -> Option<TileKey> {
    let (_, rows) = grid.tiles_at(level);
    if tms_y >= rows {
        return None;
    }
    let key = TileKey::new(level, x, rows - 1 - tms_y);
    grid.contains_key(key).then_some(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tms_rows_count_from_the_south_and_round_trip() {
        let grid = TileGrid::geodetic(256).unwrap();
        assert_eq!(tms_from_key(&grid, TileKey::new(0, 1, 0)), (0, 1, 0));
        // Level 1: 4 x 2 tiles; relief's row 0 (north) is TMS row 1.
        assert_eq!(tms_from_key(&grid, TileKey::new(1, 3, 0)), (1, 3, 1));
        assert_eq!(tms_from_key(&grid, TileKey::new(1, 3, 1)), (1, 3, 0));
        for level in 0..6u8 {
            let (cols, rows) = grid.tiles_at(level);
            for x in [0, cols - 1] {
                for y in 0..rows {
                    let key = TileKey::new(level, x, y);
                    let (l, tx, ty) = tms_from_key(&grid, key);
                    assert_eq!(key_from_tms(&grid, l, tx, ty), Some(key));
                    // TMS row 0 is the southern-most: its extent touches -90.
                    if ty == 0 {
                        assert_eq!(grid.tile_extent(key).min_y, -90.0);
                    }
                }
            }
            assert_eq!(key_from_tms(&grid, level, 0, rows), None);
            assert_eq!(key_from_tms(&grid, level, cols, 0), None);
        }
    }
}
