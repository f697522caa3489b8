"""A sweep's result as typed records over its ``metrics.json`` (schema 2).

The schema is in docs/ARCHITECTURE.md, "metrics.json". The records are the run (:class:`SweepResult`), what
each technique is (:class:`TechniqueInfo`), each light's frame (:class:`FrameRecord`) and a technique's scores
in it (:class:`Scores`).

Each record is a read-only mapping over the JSON it stands for, with typed attributes for what the
stages read; the JSON stays the one copy, so a record written back (:meth:`SweepResult.to_json`) is
byte for byte what the sweep built. Records read from a file are lenient: an entry of the wrong
type reads as missing, as an old or edited ``metrics.json`` may have it.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, Self

__all__ = [
    "Scores",
    "TechniqueInfo",
    "FrameRecord",
    "SweepResult",
    "MaterialRow",
    "SuiteResult",
    "techniques_of",
    "technique_info",
    "malformed_techniques",
    "raw_techniques",
]


class _Record(Mapping[str, Any]):
    """A read-only mapping over one JSON object (``record``), shared, not copied."""

    __slots__ = ("record",)

    def __init__(self, record: Mapping[str, Any] | None) -> None:
        if isinstance(record, _Record):
            record = record.record
        self.record: dict[str, Any] = record if isinstance(record, dict) else {}

    @classmethod
    def of(cls, record: Mapping[str, Any] | None) -> Self:
        """``record`` as this kind of record (itself if it is one already)."""
        if isinstance(record, cls):
            return record
        return cls(record)

    def __getitem__(self, key: str) -> Any:
        return self.record[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.record)

    def __len__(self) -> int:
        return len(self.record)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.record!r})"

    def _number(self, key: str) -> float | None:
        v = self.record.get(key)
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None

    def _object(self, key: str) -> dict[str, Any]:
        v = self.record.get(key)
        return v if isinstance(v, dict) else {}

    def _scores(self, key: str) -> Scores | None:
        v = self.record.get(key)
        return Scores(v) if isinstance(v, dict) else None


class Scores(_Record):
    """One technique's scores in one frame, or the frame's ``no_shadows`` or ``floor``.

    A technique's scores are ``frames[i].techniques.NAME``. They give ``visibility_mae``, ``flip_mean``, ...
    by name, and its files.
    """

    __slots__ = ()

    @property
    def visibility_mae(self) -> float | None:
        """Mean ``|F - V|`` over the whole image."""
        return self._number("visibility_mae")

    @property
    def visibility_mae_facing(self) -> float | None:
        """Mean ``|F - V|`` over the pixels facing the light."""
        return self._number("visibility_mae_facing")

    @property
    def flip_mean(self) -> float | None:
        """Mean FLIP against the truth."""
        return self._number("flip_mean")

    @property
    def seconds(self) -> float | None:
        """The technique's render time for the frame, in seconds."""
        return self._number("seconds")

    @property
    def files(self) -> dict[str, Any]:
        """Its files, relative to the report (``image``, ``png``, ``factor``, ...)."""
        return self._object("files")


class TechniqueInfo(_Record):
    """What a technique is in a run (``techniques.NAME``): its label, settings and files' stem."""

    __slots__ = ("name",)

    def __init__(self, name: str, record: Mapping[str, Any] | None) -> None:
        super().__init__(record)
        self.name = name

    @classmethod
    def of(cls, record: Mapping[str, Any] | None) -> Self:
        """Refused: a technique's record needs its name (``TechniqueInfo(name, record)``)."""
        raise TypeError("TechniqueInfo needs its name: TechniqueInfo(name, record)")

    @property
    def label(self) -> str:
        """Its name in tables and plots."""
        return str(self.record.get("label", self.name))

    @property
    def file_stem(self) -> str:
        """The stem of its files in each frame's folder."""
        return str(self.record.get("file_stem", self.name))

    @property
    def parameters(self) -> dict[str, Any]:
        """Its settings in this run."""
        return self._object("parameters")

    @property
    def fit_of(self) -> str | None:
        """The shipped technique whose textures this one fits, if it is a fit."""
        v = self.record.get("fit_of")
        return v if isinstance(v, str) else None


class FrameRecord(_Record):
    """One light's frame (``frames[i]``): where the light was and every technique's scores."""

    __slots__ = ()

    @property
    def azimuth_deg(self) -> float | None:
        """The light's azimuth, degrees (docs/ARCHITECTURE.md, "Conventions")."""
        return self._number("azimuth_deg")

    @property
    def elevation_deg(self) -> float | None:
        """The light's elevation, degrees."""
        return self._number("elevation_deg")

    @property
    def techniques(self) -> dict[str, Scores]:
        """``{name: its scores}``, in the run's order."""
        return techniques_of(self.record)

    def scores(self, name: str) -> Scores | None:
        """Technique ``name``'s scores in this frame, ``None`` if it has none."""
        return self.techniques.get(name)

    @property
    def no_shadows(self) -> Scores | None:
        """The scores of ``F = 1``, the unshadowed shading (the baseline)."""
        return self._scores("no_shadows")

    @property
    def floor(self) -> Scores | None:
        """The scores of perfect shadows (the unshadowed shading times the truth's ``V``)."""
        return self._scores("floor")

    @property
    def files(self) -> dict[str, Any]:
        """The truth's files, relative to the report."""
        return self._object("files")


class SweepResult(_Record):
    """A sweep's result: ``metrics.json``'s content, with its techniques and frames as records.

    Examples
    --------
    >>> r = SweepResult.of({"techniques": {"pom": {"label": "ray march"}},
    ...                     "frames": [{"elevation_deg": 30, "techniques": {"pom": {"flip_mean": 0.1}}}]})
    >>> r.names, r.techniques["pom"].label, r.frames[0].scores("pom").flip_mean
    (['pom'], 'ray march', 0.1)
    """

    __slots__ = ()

    def to_json(self) -> dict[str, Any]:
        """Return the JSON object, as written to ``metrics.json`` (the same object: nothing is copied)."""
        return self.record

    @property
    def techniques(self) -> dict[str, TechniqueInfo]:
        """``{name: what it is}``, in the run's order."""
        return technique_info(self.record)

    @property
    def names(self) -> list[str]:
        """The techniques' names, in the run's order."""
        return list(self.techniques)

    @property
    def chosen(self) -> list[str]:
        """The techniques the run was asked for (``parameters.techniques``), in order."""
        params = self.record.get("parameters")
        names = params.get("techniques") if isinstance(params, dict) else None
        return [n for n in names if isinstance(n, str)] if isinstance(names, list) else []

    @property
    def frames(self) -> list[FrameRecord]:
        """Every frame, in the sweep's order (an entry that is not an object is left out)."""
        frames = self.record.get("frames")
        if not isinstance(frames, list):
            return []
        return [FrameRecord(f) for f in frames if isinstance(f, dict)]

    def set_techniques(self, info: dict[str, dict[str, Any]]) -> None:
        """Replace ``techniques`` (what each technique is) with ``info``, in its order."""
        self.record["techniques"] = info


class MaterialRow(_Record):
    """One material of a suite: its status and each technique's means over its sweep.

    It is ``suite.json``'s ``materials[i]``.
    """

    __slots__ = ()

    @property
    def techniques(self) -> dict[str, Scores]:
        """``{name: its means}``, in the run's order."""
        return techniques_of(self.record)

    @property
    def no_shadows(self) -> Scores | None:
        """The means of ``F = 1``."""
        return self._scores("no_shadows")


class SuiteResult(_Record):
    """A suite's result (``suite.json``): what each technique is, and every material's row."""

    __slots__ = ()

    @property
    def techniques(self) -> dict[str, TechniqueInfo]:
        """``{name: what it is}`` over every material."""
        return technique_info(self.record)

    @property
    def names(self) -> list[str]:
        """The techniques' names."""
        return list(self.techniques)

    @property
    def materials(self) -> list[MaterialRow]:
        """Every material's row, in the overview's order."""
        rows = self.record.get("materials")
        return [MaterialRow(r) for r in rows if isinstance(r, dict)] if isinstance(rows, list) else []


def techniques_of(record: Mapping[str, Any] | None) -> dict[str, Scores]:
    """Return ``{name: its scores}`` from any record that scores techniques by name.

    They are read from the record's ``techniques`` object; such a record is a sweep's frame, a suite's
    material, a row of ``views.json`` or ``models.json``. An entry that is not an object is left out, and a
    record without one gives ``{}``.
    """
    if isinstance(record, _Record):
        record = record.record
    per = record.get("techniques") if isinstance(record, dict) else None
    if not isinstance(per, dict):
        return {}
    return {n: Scores(r) for n, r in per.items() if isinstance(r, dict)}


def technique_info(record: Mapping[str, Any] | None) -> dict[str, TechniqueInfo]:
    """Return the ``techniques`` object of a run's record as ``{name: what it is}``.

    A run's record is ``metrics.json``, ``suite.json``, and the like.
    """
    if isinstance(record, _Record):
        record = record.record
    info = record.get("techniques") if isinstance(record, dict) else None
    if not isinstance(info, dict):
        return {}
    return {n: TechniqueInfo(n, r) for n, r in info.items() if isinstance(r, dict)}


def malformed_techniques(record: Mapping[str, Any] | None) -> list[str]:
    """Return the names under a record's ``techniques`` whose entry is not an object.

    These are what a file's check names; the records leave them out.
    """
    if isinstance(record, _Record):
        record = record.record
    per = record.get("techniques") if isinstance(record, dict) else None
    return [n for n, r in per.items() if not isinstance(r, dict)] if isinstance(per, dict) else []


def raw_techniques(record: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """Return a record's ``techniques`` object as stored, for the code that builds or checks one.

    It is ``{}`` where the record has none, ``None`` where it is not an object.
    """
    if isinstance(record, _Record):
        record = record.record
    per = record.get("techniques", {}) if isinstance(record, dict) else {}
    return per if isinstance(per, dict) else ({} if per is None else None)
