"""The structures ``nodes/identified.py`` reads through ctypes are laid out as the installed headers say.

``rmw_message_info_t`` (with its ``rmw_gid_t``) and ``rcutils_uint8_array_t``
(``rcl_serialized_message_t``, with its ``rcutils_allocator_t``) are compiled
with the C compiler against the headers the ROS wheels install in the venv,
and their ``sizeof`` and field offsets compared with the ctypes mirrors: an
rmw whose layout moved would have the subscription read the wrong bytes.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

PROGRAM = r"""
#include <stdio.h>
#include <stddef.h>
#include <rmw/types.h>
#include <rcutils/types/uint8_array.h>
int main(void) {
  printf("%zu %zu %zu %zu %zu %zu %zu %zu %zu\n",
         sizeof(rmw_message_info_t), offsetof(rmw_message_info_t, received_timestamp),
         offsetof(rmw_message_info_t, publication_sequence_number),
         offsetof(rmw_message_info_t, publisher_gid),
         offsetof(rmw_message_info_t, from_intra_process),
         sizeof(rmw_gid_t), offsetof(rmw_gid_t, data),
         sizeof(rcutils_uint8_array_t), offsetof(rcutils_uint8_array_t, allocator));
  printf("%zu %d\n", sizeof(rcutils_allocator_t), (int)RMW_GID_STORAGE_SIZE);
  return 0;
}
"""


def test_the_ctypes_structures_match_the_installed_headers(tmp_path: Path) -> None:
    from servo_axis.nodes import identified as ids

    include = Path(sys.prefix) / "include"
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None or not (include / "rmw" / "rmw" / "types.h").is_file():
        pytest.skip("no C compiler or no rmw headers in the venv to compare with")
    (tmp_path / "layout.c").write_text(PROGRAM)
    flags = [f"-I{d}" for d in sorted(include.iterdir()) if d.is_dir()]
    exe = tmp_path / "layout"
    subprocess.run([compiler, *flags, str(tmp_path / "layout.c"), "-o", str(exe)], check=True)
    first, second = subprocess.run(
        [str(exe)], check=True, capture_output=True, text=True
    ).stdout.splitlines()
    info = ids.MessageInfo
    assert [int(v) for v in first.split()] == [
        ctypes.sizeof(info),
        info.received_timestamp.offset,
        info.publication_sequence_number.offset,
        info.publisher_gid.offset,
        info.from_intra_process.offset,
        ctypes.sizeof(ids.Gid),
        ids.Gid.data.offset,
        ctypes.sizeof(ids.Uint8Array),
        ids.Uint8Array.allocator.offset,
    ]
    assert [int(v) for v in second.split()] == [ctypes.sizeof(ids.Allocator), ids.GID_SIZE]
