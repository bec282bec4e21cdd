//! `imud.ImudError` and how a library error becomes one: the whole context chain on one line,
//! `a: b: c`, exactly as the command-line clients print it after `tool: error: ` (so a bad
//! line of a text recording says its file and line in Python too).

use pyo3::PyErr;
use pyo3::create_exception;
use pyo3::exceptions::PyException;

create_exception!(
    imud,
    ImudError,
    PyException,
    "An imud analysis or reader failed; the message is the command-line client's (file, line, what to do)."
);

/// The error, its contexts first, as one `ImudError`.
pub fn to_py(e: anyhow::Error) -> PyErr {
    ImudError::new_err(format!("{e:#}"))
}

/// `Result<T, anyhow::Error>` to `PyResult<T>`.
pub trait IntoPy<T> {
    /// The error as an [`ImudError`].
    fn py_err(self) -> pyo3::PyResult<T>;
}

impl<T> IntoPy<T> for anyhow::Result<T> {
    fn py_err(self) -> pyo3::PyResult<T> {
        self.map_err(to_py)
    }
}
