//! The few Parquet column shapes a LeRobot dataset needs, written through the `parquet`
//! crate's low-level column writers (no Arrow: its crates would double the build for what
//! eight column kinds need). The layouts are the ones pyarrow writes, so that `datasets`,
//! pandas and pyarrow read them as they read LeRobot's own files: a list is the three-level
//! `LIST` group (`list` / `element`), an image is Hugging Face's `struct<bytes, path>`.

use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use parquet::basic::{Compression, LogicalType, Repetition, Type as Physical};
use parquet::data_type::{ByteArrayType, DoubleType, FloatType, Int64Type};

pub use parquet::data_type::ByteArray;
use parquet::errors::ParquetError;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;

use crate::error::RecordError;

/// One column's values for one row group.
#[derive(Debug, Clone)]
pub enum Values {
    /// `float` per row.
    F32(Vec<f32>),
    /// `int64` per row.
    I64(Vec<i64>),
    /// `string` per row.
    Str(Vec<String>),
    /// `list<float>` per row.
    F32List(Vec<Vec<f32>>),
    /// `list<double>` per row.
    F64List(Vec<Vec<f64>>),
    /// `list<string>` per row.
    StrList(Vec<Vec<String>>),
    /// An image per row: Hugging Face's `struct<bytes: binary, path: string>`, the encoded
    /// file's bytes and no path.
    Image(Vec<ByteArray>),
}

impl Values {
    /// Rows held.
    pub fn len(&self) -> usize {
        match self {
            Values::F32(v) => v.len(),
            Values::I64(v) => v.len(),
            Values::Str(v) => v.len(),
            Values::F32List(v) => v.len(),
            Values::F64List(v) => v.len(),
            Values::StrList(v) => v.len(),
            Values::Image(v) => v.len(),
        }
    }

    /// Whether it holds no row.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The column's schema, named `name`.
    fn schema(&self, name: &str) -> Result<Type, ParquetError> {
        let leaf = |name: &str, t: Physical, rep: Repetition, string: bool| {
            Type::primitive_type_builder(name, t)
                .with_repetition(rep)
                .with_logical_type(string.then_some(LogicalType::String))
                .build()
        };
        let list = |t: Physical, string: bool| -> Result<Type, ParquetError> {
            let element = leaf("element", t, Repetition::REQUIRED, string)?;
            let group = Type::group_type_builder("list")
                .with_repetition(Repetition::REPEATED)
                .with_fields(vec![Arc::new(element)])
                .build()?;
            Type::group_type_builder(name)
                .with_repetition(Repetition::REQUIRED)
                .with_logical_type(Some(LogicalType::List))
                .with_fields(vec![Arc::new(group)])
                .build()
        };
        match self {
            Values::F32(_) => leaf(name, Physical::FLOAT, Repetition::REQUIRED, false),
            Values::I64(_) => leaf(name, Physical::INT64, Repetition::REQUIRED, false),
            Values::Str(_) => leaf(name, Physical::BYTE_ARRAY, Repetition::REQUIRED, true),
            Values::F32List(_) => list(Physical::FLOAT, false),
            Values::F64List(_) => list(Physical::DOUBLE, false),
            Values::StrList(_) => list(Physical::BYTE_ARRAY, true),
            Values::Image(_) => {
                let bytes = leaf("bytes", Physical::BYTE_ARRAY, Repetition::OPTIONAL, false)?;
                let path = leaf("path", Physical::BYTE_ARRAY, Repetition::OPTIONAL, true)?;
                Type::group_type_builder(name)
                    .with_repetition(Repetition::REQUIRED)
                    .with_fields(vec![Arc::new(bytes), Arc::new(path)])
                    .build()
            }
        }
    }
}

/// The definition and repetition levels of a list column whose rows hold `lens` elements
/// (a required list of required elements: level 1 for an element, 0 for an empty row).
fn list_levels(lens: impl Iterator<Item = usize>) -> (Vec<i16>, Vec<i16>) {
    let (mut def, mut rep) = (Vec::new(), Vec::new());
    for n in lens {
        if n == 0 {
            def.push(0);
            rep.push(0);
        }
        for k in 0..n {
            def.push(1);
            rep.push(i16::from(k > 0));
        }
    }
    (def, rep)
}

/// A Parquet file being written, one row group at a time, every group with the same columns.
pub struct Table {
    path: std::path::PathBuf,
    names: Vec<String>,
    writer: Option<SerializedFileWriter<File>>,
    metadata: Vec<KeyValue>,
}

impl Table {
    /// A table to be written to `path` (created at the first group), with `metadata` in the
    /// file's key-value metadata (pandas' schema, for instance).
    pub fn new(path: &Path, metadata: Vec<(String, String)>) -> Table {
        Table {
            path: path.to_path_buf(),
            names: Vec::new(),
            writer: None,
            metadata: metadata
                .into_iter()
                .map(|(k, v)| KeyValue::new(k, v))
                .collect(),
        }
    }

    fn error(path: &Path, e: impl std::fmt::Display) -> RecordError {
        RecordError::Io {
            what: "writing",
            path: path.to_path_buf(),
            source: std::io::Error::other(e.to_string()),
        }
    }

    fn err(&self, e: impl std::fmt::Display) -> RecordError {
        Table::error(&self.path, e)
    }

    /// Writes one row group: `columns`, named, each with as many rows (the first group's
    /// names and kinds are the file's schema).
    pub fn write_group<S: AsRef<str>>(
        &mut self,
        columns: &[(S, Values)],
    ) -> Result<(), RecordError> {
        let rows = columns.first().map_or(0, |(_, v)| v.len());
        if columns.iter().any(|(_, v)| v.len() != rows) {
            return Err(self.err("columns of different lengths in one row group"));
        }
        if self.writer.is_none() {
            self.open(columns)?;
        } else if columns
            .iter()
            .map(|(n, _)| n.as_ref())
            .ne(self.names.iter())
        {
            return Err(self.err("a row group with other columns than the file's"));
        }
        let path = self.path.clone();
        let err = |e: ParquetError| Table::error(&path, e);
        let writer = self.writer.as_mut().expect("opened above");
        let mut group = writer.next_row_group().map_err(err)?;
        for (_, values) in columns {
            write_values(&mut group, values).map_err(err)?;
        }
        group.close().map_err(err)?;
        Ok(())
    }

    fn open<S: AsRef<str>>(&mut self, columns: &[(S, Values)]) -> Result<(), RecordError> {
        let fields = columns
            .iter()
            .map(|(n, v)| v.schema(n.as_ref()).map(Arc::new))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| self.err(e))?;
        let schema = Type::group_type_builder("schema")
            .with_fields(fields)
            .build()
            .map_err(|e| self.err(e))?;
        let props = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_created_by(concat!("ferrobot-record ", env!("CARGO_PKG_VERSION")).into())
            .set_key_value_metadata(Some(self.metadata.clone()))
            .build();
        let file = File::create_new(&self.path).map_err(|source| RecordError::Io {
            what: "creating",
            path: self.path.clone(),
            source,
        })?;
        let writer = SerializedFileWriter::new(file, Arc::new(schema), Arc::new(props))
            .map_err(|e| self.err(e))?;
        self.names = columns
            .iter()
            .map(|(n, _)| n.as_ref().to_string())
            .collect();
        self.writer = Some(writer);
        Ok(())
    }

    /// Finishes the file.
    pub fn finish(mut self) -> Result<(), RecordError> {
        if let Some(w) = self.writer.take() {
            w.close().map_err(|e| self.err(e))?;
        }
        Ok(())
    }
}

/// Writes `values` as the next column (or the next two, for an image) of `group`.
fn write_values(
    group: &mut parquet::file::writer::SerializedRowGroupWriter<'_, File>,
    values: &Values,
) -> Result<(), ParquetError> {
    let bytes = |v: &[String]| -> Vec<ByteArray> {
        v.iter()
            .map(|s| ByteArray::from(s.as_bytes().to_vec()))
            .collect()
    };
    let mut col = group
        .next_column()?
        .ok_or_else(|| ParquetError::General("fewer columns than the schema".into()))?;
    match values {
        Values::F32(v) => col.typed::<FloatType>().write_batch(v, None, None)?,
        Values::I64(v) => col.typed::<Int64Type>().write_batch(v, None, None)?,
        Values::Str(v) => col
            .typed::<ByteArrayType>()
            .write_batch(&bytes(v), None, None)?,
        Values::F32List(v) => {
            let (def, rep) = list_levels(v.iter().map(Vec::len));
            let flat: Vec<f32> = v.iter().flatten().copied().collect();
            col.typed::<FloatType>()
                .write_batch(&flat, Some(&def), Some(&rep))?
        }
        Values::F64List(v) => {
            let (def, rep) = list_levels(v.iter().map(Vec::len));
            let flat: Vec<f64> = v.iter().flatten().copied().collect();
            col.typed::<DoubleType>()
                .write_batch(&flat, Some(&def), Some(&rep))?
        }
        Values::StrList(v) => {
            let (def, rep) = list_levels(v.iter().map(Vec::len));
            let flat: Vec<String> = v.iter().flatten().cloned().collect();
            col.typed::<ByteArrayType>()
                .write_batch(&bytes(&flat), Some(&def), Some(&rep))?
        }
        Values::Image(v) => {
            col.typed::<ByteArrayType>()
                .write_batch(v, Some(&vec![1; v.len()]), None)?;
            col.close()?;
            // The path: null in every row.
            let mut path = group
                .next_column()?
                .ok_or_else(|| ParquetError::General("fewer columns than the schema".into()))?;
            path.typed::<ByteArrayType>()
                .write_batch(&[], Some(&vec![0; v.len()]), None)?;
            return path.close();
        }
    };
    col.close()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn list_levels_mark_each_row_s_first_element_and_empty_rows() {
        let (def, rep) = list_levels([2, 0, 1].into_iter());
        assert_eq!(def, vec![1, 1, 0, 1]);
        assert_eq!(rep, vec![0, 1, 0, 0]);
    }
}
