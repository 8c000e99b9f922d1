"""shared.provenance: hashes of files, folders, configurations and modules change with
content and not with location or order."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

from shared.provenance import config_sha256, file_sha256, folder_sha256, inputs_record, module_sha256


def test_file_hash_is_sha256_of_the_bytes_whatever_the_chunks(tmp_path: Path) -> None:
    data = bytes(range(256)) * 41
    path = tmp_path / "data.bin"
    path.write_bytes(data)
    expected = hashlib.sha256(data).hexdigest()
    assert file_sha256(path) == expected == file_sha256(path, chunk_bytes=7)
    path.write_bytes(data[:-1] + b"\0")
    assert file_sha256(path) != expected


def _slice(folder: Path, second: bytes = b"two") -> Path:
    (folder / "sub").mkdir(parents=True)
    (folder / "a.tif").write_bytes(b"one")
    (folder / "sub" / "b.tif").write_bytes(second)
    return folder


def test_folder_hash_follows_names_and_bytes_not_location_or_hidden_files(tmp_path: Path) -> None:
    digest, count = folder_sha256(_slice(tmp_path / "here"))
    assert count == 2
    assert folder_sha256(_slice(tmp_path / "elsewhere" / "deeper")) == (digest, 2)
    hidden = _slice(tmp_path / "hidden")
    (hidden / ".DS_Store").write_bytes(b"x")
    (hidden / ".cache").mkdir()
    (hidden / ".cache" / "c.tif").write_bytes(b"y")
    assert folder_sha256(hidden) == (digest, 2)
    assert folder_sha256(_slice(tmp_path / "edited", b"tw0"))[0] != digest
    renamed = _slice(tmp_path / "renamed")
    (renamed / "a.tif").rename(renamed / "c.tif")
    assert folder_sha256(renamed)[0] != digest


def test_config_hash_ignores_key_order_only() -> None:
    first = {"a": 1, "b": {"c": [1, 2], "d": "x"}}
    second = {"b": {"d": "x", "c": [1, 2]}, "a": 1}
    assert config_sha256(first) == config_sha256(second)
    assert config_sha256(first) != config_sha256({"a": 1, "b": {"c": [2, 1], "d": "x"}})
    assert config_sha256(None) == config_sha256({}) == hashlib.sha256(b"{}").hexdigest()


def test_inputs_record_lists_files_and_folders_that_exist(tmp_path: Path) -> None:
    path = tmp_path / "f.nc"
    path.write_bytes(b"netcdf")
    folder = _slice(tmp_path / "slices")
    records = json.loads(inputs_record([path, folder, tmp_path / "missing.nc"]))
    assert records == [{"path": str(path), "sha256": hashlib.sha256(b"netcdf").hexdigest()},
                       {"path": str(folder), "sha256": folder_sha256(folder)[0], "files": 2}]


def _tree(root: Path) -> Path:
    """A package ``shared`` in ``root`` whose module ``entry`` imports ``shared.used``."""
    package = root / "shared"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text('"""pkg"""\n')
    (package / "entry.py").write_text("from shared.used import VALUE\n\nprint(VALUE)\n")
    (package / "used.py").write_text("VALUE = 1\n")
    (package / "other.py").write_text("VALUE = 2\n")
    return package / "entry.py"


def test_module_hash_follows_its_imports_and_not_where_the_tree_lies(tmp_path: Path) -> None:
    entry = _tree(tmp_path / "one")
    digest = module_sha256(entry)
    copy = tmp_path / "two" / "deeper"
    shutil.copytree(tmp_path / "one", copy)
    assert module_sha256(copy / "shared" / "entry.py") == digest
    (copy / "shared" / "other.py").write_text("VALUE = 3\n")
    assert module_sha256(copy / "shared" / "entry.py") == digest
    (copy / "shared" / "used.py").write_text("VALUE = 3\n")
    assert module_sha256(copy / "shared" / "entry.py") != digest
    entry.write_text(entry.read_text() + "print(VALUE + 1)\n")
    assert module_sha256(entry) != digest
