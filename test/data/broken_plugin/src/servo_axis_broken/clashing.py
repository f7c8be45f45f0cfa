"""An identification method whose schema redeclares a key of the identifier node itself."""

from __future__ import annotations

from servo_axis.params.param import Param
from servo_axis.params.registry import IdentifierEntry

METHOD = IdentifierEntry(
    schema={"rls_period_s": Param(0.004, unit="s", above=0.0, meaning="clashes")},
    build=lambda values: None,  # type: ignore[arg-type,return-value]
)
