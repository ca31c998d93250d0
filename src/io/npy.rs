//! `.npy` files (numpy's array format) of the library's `ndarray` results, written atomically
//! like every other output.

use std::path::Path;

/// Writes `array` to `path` as `.npy` (little-endian, C order: the last axis fastest).
pub fn write_npy<A, D>(path: &Path, array: &ndarray::ArrayRef<A, D>) -> anyhow::Result<()>
where
    A: ndarray_npy::WritableElement,
    D: ndarray::Dimension,
{
    use ndarray_npy::WriteNpyExt;
    super::atomic::write_atomically(path, |out| {
        array.write_npy(out).map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok(())
    })
}
