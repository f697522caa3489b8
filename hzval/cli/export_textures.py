"""``hzval export-textures``: a run's textures as KTX2 (:mod:`hzval.commands.export_textures`)."""

from __future__ import annotations

from pathlib import Path

from hzval.core import errors


def add_parser(sub) -> None:
    """Add the ``export-textures`` command's parser to ``sub``."""
    p = sub.add_parser(
        "export-textures",
        help="write a run's textures as KTX2 files an engine loads, in the storage they were scored with",
        description="Write one KTX2 file per texture the run's techniques read (horizon<i>, normal, ambient, "
        "bent_normal, ssbump), in the storage each was scored with (BC7, BC1, BC4, 8-bit, half float), "
        "with every mip level, and textures.json saying what each channel means (docs/outputs.md).",
    )
    p.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="what hzval sweep, bake or fit wrote")
    p.add_argument("--zstd", action="store_true", help="supercompress each level with Zstandard")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``hzval export-textures`` with the parsed ``args``; return its exit code."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import export_textures

    written = export_textures.export(args.run_dir, args.out, zstd=args.zstd, force=args.force)
    print(f"wrote {len(written)} files to {args.out}: {', '.join(p.name for p in written)}")
    return errors.EXIT_OK
