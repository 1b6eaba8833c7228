"""Options: every setting declared once (default, range, help), one checker, one error, the CLI generated from them."""

from __future__ import annotations

import argparse
import dataclasses
import math

import pytest

import lsys3d
from lsys3d.cli import build_parser, main
from lsys3d.errors import OptionsError
from lsys3d.exchange import ExportOptions
from lsys3d.library.forest import ForestOptions
from lsys3d.look.attributes import AttributeOptions
from lsys3d.look.bark import BarkColorOptions
from lsys3d.look.growth import GrowthOptions
from lsys3d.look.leaves import LeafOptions
from lsys3d.look.lod import LodOptions
from lsys3d.look.organs import OrganOptions
from lsys3d.look.rig import RigOptions
from lsys3d.look.wind import WindOptions
from lsys3d.mesh.cleanup import CleanupOptions
from lsys3d.mesh.sweep import SweepOptions
from lsys3d.mesh.union.union import UnionOptions
from lsys3d.options import Options, add_arguments, check_value, flat_fields, from_arguments, spec_of
from lsys3d.pipeline import GenerateOptions, Limits
from lsys3d.render.preview import PreviewOptions
from lsys3d.turtle import FormOptions, TurtleOptions, TurtleOverrides
from lsys3d.turtle.diagnostics import Checks

CLASSES = [
    Limits,
    Checks,
    SweepOptions,
    UnionOptions,
    BarkColorOptions,
    AttributeOptions,
    LeafOptions,
    OrganOptions,
    RigOptions,
    TurtleOptions,
    FormOptions,
    ExportOptions,
    PreviewOptions,
    ForestOptions,
    WindOptions,
    GrowthOptions,
]


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_every_field_is_declared_with_its_spec(cls):
    assert issubclass(cls, Options)
    for f in dataclasses.fields(cls):
        spec = spec_of(f)
        assert spec is not None, f"{cls.__name__}.{f.name} has no option() declaration"
        assert spec.help and not spec.help.endswith("."), f.name
        default = getattr(cls(), f.name)
        assert check_value(spec, default, f.name) == default  # the default passes its own check


def test_generate_options_nest_one_class_per_stage():
    names = {f.name: f.type for f in dataclasses.fields(GenerateOptions)}
    assert list(names) == [
        "limits",
        "turtle",
        "form",
        "sweep",
        "union",
        "cleanup",
        "color",
        "attributes",
        "leaves",
        "organs",
        "rig",
        "wind",
        "growth",
        "checks",
        "lod",
    ]
    assert flat_fields(GenerateOptions)["strict"] == ("checks", "strict")
    flat = flat_fields(GenerateOptions)
    assert flat["sides"] == ("sweep", "sides") and flat["union"] == ("union", "enabled")
    assert flat["form"] == ("form", "enabled") and flat["pipe_model"] == ("form", "pipe_model")
    assert flat["max_modules"] == ("limits", "max_modules") and flat["bark_color_variation"] == ("color", "variation")
    assert len(flat) == len(set(flat.values()))


@pytest.mark.parametrize(
    ("cls", "field", "value", "message"),
    [
        (SweepOptions, "sides", 2, r"SweepOptions\.sides: must be in \[3, 1024\], not 2"),
        (SweepOptions, "sides", 10**400, r"SweepOptions\.sides: must be in \[3, 1024\], not 10,000,000"),
        (SweepOptions, "sides", 6.5, r"SweepOptions\.sides: must be a whole number, not 6\.5"),
        (SweepOptions, "min_width", 10**400, "too large for a floating-point number"),
        (SweepOptions, "min_width", math.nan, "must be a finite number, not nan"),
        (SweepOptions, "min_width", True, "must be a number, not True"),
        (SweepOptions, "bark_displacement", 0.6, r"must be in \[0, 0\.5\], not 0\.6"),
        (UnionOptions, "margin", -1, r"UnionOptions\.margin: must be in \[0, 1\]"),
        (UnionOptions, "enabled", 1, r"UnionOptions\.enabled: must be true or false, not 1"),
        (Limits, "max_modules", 0, r"Limits\.max_modules: must be >= 1, not 0"),
        (BarkColorOptions, "variation", 2.0, r"BarkColorOptions\.variation: must be in \[0, 1\], not 2"),
        (TurtleOptions, "tropism", (0, 1e400, 0), "must be a finite number, not inf"),
        (TurtleOptions, "tropism", (0, 10**400, 0), "too large for a floating-point number"),
        (TurtleOptions, "jitter_distribution", "gauss", "must be one of 'uniform', 'normal', not 'gauss'"),
        (ExportOptions, "units", "km", r"ExportOptions\.units: must be one of 'm', 'cm', not 'km'"),
        (PreviewOptions, "size", (0, 10), r"PreviewOptions\.size: must be in \[1, 16,384\], not 0"),
    ],
    ids=lambda v: v.__name__ if isinstance(v, type) else str(v)[:20],
)
def test_one_checker_one_error(cls, field, value, message):
    """Type, finiteness, float range and range, checked in one place for every class."""
    with pytest.raises(OptionsError, match=message):
        cls(**{field: value})


def test_an_options_error_is_an_lsystem_error_and_a_value_error():
    assert issubclass(OptionsError, lsys3d.LSystemError) and issubclass(OptionsError, ValueError)


def test_plain_round_trip_and_flat_names():
    options = GenerateOptions.from_flat(sides=6, union=False, max_segments=10, turtle={"width_jitter": 0.2})
    assert GenerateOptions.from_plain(options.plain()) == options
    assert options.sweep.sides == 6 and not options.union.enabled and options.limits.max_segments == 10
    assert options.turtle == {"width_jitter": 0.2} and isinstance(options.turtle, TurtleOverrides)
    # a recipe may name a nested field by its flat name (golden files written by lsys3d 0.1.0 did)
    assert GenerateOptions.from_plain({"union": False, "sides": 6}) == GenerateOptions.from_flat(union=False, sides=6)
    with pytest.raises(OptionsError, match="unknown option 'sidez'"):
        GenerateOptions.from_flat(sidez=6)
    with pytest.raises(OptionsError, match="unknown option 'wobble'"):
        GenerateOptions.from_plain({"wobble": 1})
    with pytest.raises(OptionsError, match=r"GenerateOptions\.sweep: options must be a table"):
        GenerateOptions.from_plain({"sweep": 3})


def test_cli_flags_come_from_the_fields():
    parser = argparse.ArgumentParser()
    add_arguments(parser, GenerateOptions)
    flags = {a.option_strings[0] for a in parser._actions if a.option_strings and a.dest.startswith("opt__")}
    expected = set()
    for cls in (
        Limits,
        FormOptions,
        SweepOptions,
        UnionOptions,
        CleanupOptions,
        BarkColorOptions,
        AttributeOptions,
        LeafOptions,
        RigOptions,
        OrganOptions,
        WindOptions,
        GrowthOptions,
        Checks,
        LodOptions,
    ):
        for f in dataclasses.fields(cls):
            spec = spec_of(f)
            if spec.cli:
                name = (spec.name or f.name).replace("_", "-")
                expected.add(f"--no-{name}" if f.default is True else f"--{name}")
    assert flags == expected
    help_text = " ".join(parser.format_help().split())
    assert "in [3, 1024]; default 8" in help_text  # range and default from the declaration
    args = parser.parse_args(["--sides", "6", "--no-union", "--bark-color-variation", "0.5"])
    options = from_arguments(GenerateOptions, args)
    assert options == GenerateOptions.from_flat(sides=6, union=False, bark_color_variation=0.5)
    assert from_arguments(GenerateOptions, parser.parse_args([])) == GenerateOptions()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--sides", "2"], "argument --sides: must be in [3, 1024], not 2"),
        (["--sides", "1" + "0" * 400], "argument --sides: must be in [3, 1024]"),
        (["--min-width", "1e400"], "argument --min-width: must be a finite number, not inf"),
        (["--max-modules", "x"], "argument --max-modules: expected a whole number, not 'x'"),
        (["--turtle", "step=1e400"], "turtle.step: must be a finite number, not inf"),
        (["--turtle", "tropism=[0, 1" + "0" * 400 + ", 0]"], "turtle.tropism: 1000"),
        (["--units", "km"], "argument --units: invalid choice: 'km'"),
    ],
)
def test_bad_flags_are_usage_errors(args, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main(["generate", "koch", "-n", "1", "-o", str(tmp_path / "k.glb"), *args])
    err = capsys.readouterr().err
    assert info.value.code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_every_subcommand_builds():
    parser = build_parser()
    for command in ("generate", "preview", "stats", "derive", "check", "presets"):
        with pytest.raises(SystemExit) as info:
            parser.parse_args([command, "--help"])
        assert info.value.code == 0
