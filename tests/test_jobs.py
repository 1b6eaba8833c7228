"""Jobs files: parsing, the cross product, stable ids, shards, errors that point at the value, size predictions."""

from __future__ import annotations

import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

import lsys3d
from lsys3d.errors import BatchError
from lsys3d.library.jobs import (
    MAX_JOBS,
    Job,
    JobSize,
    OptionNameError,
    options_from_names,
    parse_shard,
    predict_size,
    read_jobs,
    shard,
)
from lsys3d.pipeline import GenerateOptions, draw

ISSUE_EXAMPLE = """\
[[jobs]]
grammar = "tree3d"          # a preset or a path relative to the jobs file
seeds = "0-49"              # a range "A-B" or a list [0, 3, 7]
formats = ["glb", "usdc"]
options = { sides = 6 }     # generate's options by their CLI names
"""


def jobs_file(tmp_path, text: str, name: str = "jobs.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_the_issue_example(tmp_path):
    jobs = read_jobs(jobs_file(tmp_path, ISSUE_EXAMPLE))
    assert [job.id for job in jobs] == [f"tree3d_s{s}" for s in range(50)]
    job = jobs[7]
    assert job.paths == ("tree3d/tree3d_s7.glb", "tree3d/tree3d_s7.usdc")
    assert job.seed == 7 and job.iterations == lsys3d.load_preset("tree3d").iterations
    assert job.options.sweep.sides == 6
    assert job.grammar_source == "presets/tree3d.toml" and job.grammar_error is None
    assert job.grammar().name == "tree3d"


def test_cross_product_in_file_order_and_stable_ids(tmp_path):
    text = """\
[defaults]
formats = ["usda"]
options = { iterations = 2 }

[[jobs]]
grammar = ["koch", "dragon"]
seeds = [3, "5-6"]

[[jobs]]
grammar = "koch"
name = "koch_lod1"
seeds = 1
formats = [".GLB"]
options = { sides = 4, no-union = true }
"""
    first = read_jobs(jobs_file(tmp_path, text))
    again = read_jobs(jobs_file(tmp_path, text))
    assert first == again
    ids = [job.id for job in first]
    assert ids == ["koch_s3", "koch_s5", "koch_s6", "dragon_s3", "dragon_s5", "dragon_s6", "koch_lod1_s1"]
    lod = first[-1]
    assert lod.formats == ("glb",) and lod.paths == ("koch_lod1/koch_lod1_s1.glb",)
    assert lod.iterations == 2 and lod.options.sweep.sides == 4 and not lod.options.union.enabled  # defaults merged


def test_seeds_default_to_the_grammars_own(tmp_path):
    jobs = read_jobs(jobs_file(tmp_path, '[[jobs]]\ngrammar = "koch-stochastic"\nformats = ["svg"]\n'))
    assert [job.seed for job in jobs] == [lsys3d.load_preset("koch-stochastic").seed]
    assert not jobs[0].options.union.enabled  # a line drawing alone: no union to throw away


def test_grammar_files_are_relative_to_the_jobs_file(tmp_path, monkeypatch):
    (tmp_path / "grammars").mkdir()
    (tmp_path / "grammars" / "fern.toml").write_text('name = "fern"\naxiom = "F"\nrules = ["F -> F[+F]F"]\n')
    (tmp_path / "grammars" / "nameless.toml").write_text('axiom = "F"\nrules = ["F -> FF"]\n')
    (tmp_path / "grammars" / "broken.toml").write_text('axiom = "F"\nrules = ["F -> F[+F"]\n')
    path = jobs_file(
        tmp_path,
        '[[jobs]]\ngrammar = ["grammars/fern.toml", "grammars/nameless.toml", "grammars/broken.toml"]\n'
        'formats = ["glb"]\nseeds = "0-1"\n',
    )
    monkeypatch.chdir("/")
    jobs = read_jobs(path)
    assert [job.id for job in jobs] == ["fern_s0", "fern_s1", "nameless_s0", "nameless_s1", "broken_s0", "broken_s1"]
    assert jobs[0].grammar_source == str((tmp_path / "grammars" / "fern.toml").resolve())
    # a grammar that does not parse is not a jobs-file error: its jobs carry the grammar's own message
    assert jobs[4].grammar_error is not None and "broken.toml:2:" in jobs[4].grammar_error
    assert "unbalanced" in jobs[4].grammar_error


def test_options_are_generates_by_their_cli_names():
    n, options, export = options_from_names(
        {
            "iterations": 3,
            "sides": 5,
            "no-union": True,
            "max_segments": 99,  # underscores too
            "turtle": {"width_jitter": 0.2, "tropism": [0, -1, 0]},
            "bark-color-variation": 0.3,
            "units": "cm",
            "up-axis": "Z",
            "instance-leaves": True,
            "skeleton-curves": False,
        }
    )
    assert n == 3 and options.sweep.sides == 5 and not options.union.enabled and options.limits.max_segments == 99
    assert options.turtle == {"width_jitter": 0.2, "tropism": (0.0, -1.0, 0.0)}
    assert options.color.variation == 0.3
    assert (export.units, export.up_axis, export.instance_leaves, export.skeleton_curves) == ("cm", "Z", True, False)
    assert options_from_names({}) == (None, GenerateOptions(), lsys3d.ExportOptions())


@pytest.mark.parametrize(
    ("names", "key", "fragment"),
    [
        ({"sidez": 3}, "sidez", "unknown option 'sidez' (known: "),
        ({"output": "x.glb"}, "output", "unknown option 'output'"),
        ({"seed": 3}, "seed", "unknown option 'seed'"),
        ({"sides": 2}, "sides", "sides: must be in [3, 1024], not 2"),
        ({"sides": "many"}, "sides", "sides: must be a whole number, not 'many'"),
        ({"sides": True}, "sides", "sides: must be a whole number, not True"),
        ({"no-union": 1}, "no-union", "a switch takes true or false"),
        ({"units": "km"}, "units", "units: must be one of 'm', 'cm', not 'km'"),
        ({"bark-displacement": 0.9}, "bark-displacement", "must be in [0, 0.5], not 0.9"),
        ({"turtle": {"wobble": 1}}, "turtle", "turtle: unknown setting 'wobble' (known: "),
        ({"turtle": {"jitter_distribution": "cauchy"}}, "turtle", "turtle.jitter_distribution: must be one of"),
        ({"sides": [3, 4]}, "sides", "sides: must be a whole number, not [3, 4]"),
    ],
)
def test_option_errors_name_the_option(names, key, fragment):
    with pytest.raises(OptionNameError, match=re.escape(fragment)) as info:
        options_from_names(names)
    assert info.value.key == key


@pytest.mark.parametrize(
    ("text", "where", "fragment"),
    [
        ("[[jobs]]\ngrammar = \n", ":2:11", "TOML syntax error"),
        ('title = "x"\n[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\n', ":1:1", "unknown key 'title'"),
        ("", "", "no jobs"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\ncolour = 1\n', ":4:10", "unknown key 'colour'"),
        ('[[jobs]]\nformats = ["svg"]\n', ":1:1", "grammar: expected a preset name"),
        ('[[jobs]]\ngrammar = "kosh"\nformats = ["svg"]\n', ":2:11", "no bundled preset named 'kosh'"),
        ('[[jobs]]\ngrammar = "gone.toml"\nformats = ["svg"]\n', ":2:11", "no such grammar file"),
        ('[[jobs]]\ngrammar = "koch"\n', ":1:1", "formats: missing"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["fbx"]\n', ":3:11", "unknown format 'fbx'"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["glb", ".glb"]\n', ":3:11", "'.glb' is given twice"),
        ('[[jobs]]\ngrammar = "koch"\nformats = []\n', ":3:11", "formats: the list is empty"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = "9-3"\n', ":4:9", "first <= last"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = "0-x"\n', ":4:9", 'expected "A-B"'),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = [1, "0-2"]\n', ":4:9", "seed 1 is given twice"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = -1\n', ":4:9", "whole numbers >= 0"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = true\n', ":4:9", "not True"),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = []\n', ":4:9", "the list is empty"),
        (
            '[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\noptions = { iterations = 2, sidez = 3 }\n',
            ":4:37",
            "options: unknown option 'sidez'",
        ),
        (
            '[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\n[jobs.options]\nsides = 2\n',
            ":5:9",
            "options: sides: must be in [3, 1024], not 2",
        ),
        ('[defaults]\noptions = { sides = 1 }\n[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\n', ":2:21", "sides"),
        (
            '[[jobs]]\ngrammar = "koch"\nformats = ["glb"]\noptions = { units = "cm" }\n',
            ":3:11",
            "glTF is always metres and Y up",
        ),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nname = "my plant"\n', ":4:8", "cannot name files"),
        ('[[jobs]]\ngrammar = ["koch", "dragon"]\nformats = ["svg"]\nname = "x"\n', ":4:8", "one name for several"),
        (
            '[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = "0-3"\n'
            '[[jobs]]\ngrammar = "koch"\nformats = ["glb"]\nseeds = 2\n',
            ":6:11",
            "job 'koch_s2' is also made by entry 1 (line 1)",
        ),
        (
            '[[jobs]]\ngrammar = "koch"\nformats = ["usdc"]\n'
            '[[jobs]]\ngrammar = "dragon"\nformats = ["usda"]\noptions = { up-axis = "Z" }\n',
            ":7:11",
            "the USD files of one library share them",
        ),
        ('[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = "0-200000"\n', ":4:9", "more than 100,000 jobs"),
    ],
)
def test_jobs_file_errors_point_at_the_value(tmp_path, text, where, fragment):
    path = jobs_file(tmp_path, text)
    with pytest.raises(BatchError) as info:
        read_jobs(path)
    message = str(info.value)
    assert message.startswith(f"{path}{where}: "), message
    assert fragment in message, message
    assert "\n" not in message


def test_missing_and_unreadable_jobs_files(tmp_path):
    with pytest.raises(BatchError, match="no such jobs file"):
        read_jobs(tmp_path / "none.toml")
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'[[jobs]]\ngrammar = "k\xf6ch"\n')
    with pytest.raises(BatchError, match="not UTF-8"):
        read_jobs(path)


def test_max_jobs_is_checked_before_the_list_is_built(tmp_path):
    path = jobs_file(tmp_path, f'[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\nseeds = "0-{10**15}"\n')
    with pytest.raises(BatchError, match=f"more than {MAX_JOBS:,} jobs"):
        read_jobs(path)


@given(count=st.integers(1, 12), n=st.integers(0, 40))
def test_shards_cover_the_job_list_exactly_once(count, n):
    jobs = list(range(n))
    slices = [shard(jobs, i, count) for i in range(1, count + 1)]
    assert sorted(x for s in slices for x in s) == jobs
    assert max(map(len, slices)) - min(map(len, slices)) <= 1  # round robin: balanced


@pytest.mark.parametrize("text", ["0/2", "3/2", "1", "a/b", "1/0", "-1/2"])
def test_bad_shards(text):
    with pytest.raises(ValueError, match="1 <= I <= N"):
        parse_shard(text)


def _job(grammar: str, options: GenerateOptions | None = None, **kw) -> tuple:
    g = lsys3d.load_preset(grammar, **kw)
    return g, options or GenerateOptions()


@pytest.mark.parametrize("name", ["tree3d", "bush", "abop-1.24d", "monopodial", "koch-stochastic", "context-1.31a"])
def test_predicted_counts_are_the_counts(name):
    grammar = lsys3d.load_preset(name)
    options = GenerateOptions()
    seed = 3
    size = predict_size(grammar, grammar.iterations, seed, options)
    modules, skeleton = draw(grammar, grammar.iterations, seed, options)
    assert size.modules == len(modules)
    assert size.segments == len(skeleton)
    assert size.bytes > size.tube_triangles > 0


def test_predicted_bytes_grow_with_the_job_and_stop_at_limits():
    grammar = lsys3d.load_preset("tree3d")
    sizes = [predict_size(grammar, n, 0, GenerateOptions()) for n in (3, 5, 7)]
    assert sizes[0].bytes < sizes[1].bytes < sizes[2].bytes
    assert predict_size(grammar, 7, 0, GenerateOptions.from_flat(union=False)).bytes < sizes[2].bytes
    # a job that stops at a limit builds only what comes before it
    stopped = predict_size(grammar, 7, 0, GenerateOptions.from_flat(max_segments=10))
    assert stopped.tube_triangles == 0 and stopped.bytes < sizes[0].bytes
    huge = predict_size(lsys3d.Grammar(axiom="F", rules=["F -> FF"]), 60, 0, GenerateOptions())
    assert huge == JobSize(huge.modules, 0, 0, huge.bytes) and huge.modules >= 2**53  # float64 counts, capped


def test_jobs_are_plain_picklable_data(tmp_path):
    import pickle

    jobs = read_jobs(jobs_file(tmp_path, ISSUE_EXAMPLE))
    assert pickle.loads(pickle.dumps(jobs)) == jobs
    assert isinstance(jobs[0], Job)
