"""Bad input gets an error that names the file, the field and the value."""

from __future__ import annotations

import math

import numpy as np
import pytest

from redysim import (
    CaseError,
    Chain,
    Joint,
    Link,
    StateError,
    Workspace,
    eliminate,
    energy,
    forward_dynamics,
    inverse_dynamics,
    load_case,
    mass_matrix,
    tip,
)
from redysim.errors import FieldError

GOOD = """
[case]
name = "T"
paper = { tables = ["study_chains"] }

[chain]
links = 3
joint = "R"
link_length = 1.0
link_mass = 2.0
radius = 0.02
inertia = "cylinder"

[initial]
q = 0.0
v = 0.0

[simulation]
t_end = 1.0
"""


def write(tmp_path, text, name="bad.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def expect(tmp_path, text, field, value_text):
    path = write(tmp_path, text)
    with pytest.raises(CaseError) as err:
        load_case(path)
    msg = str(err.value)
    assert str(path) in msg, msg
    assert field in msg, msg
    assert value_text in msg, msg
    return msg


def test_good_case_loads(tmp_path):
    case = load_case(write(tmp_path, GOOD))
    assert case.chain.n_dof == 3


@pytest.mark.parametrize("old,new,field,value", [
    ("link_mass = 2.0", "link_mass = -2.0", "chain.link_mass", "-2.0"),
    ("link_mass = 2.0", "link_mass = 0.0", "chain.link_mass", "0.0"),
    ("link_length = 1.0", "link_length = -1.0", "chain.link_length", "-1.0"),
    ("link_length = 1.0", "link_length = 0", "chain.link_length", "0"),
    ('joint = "R"', 'joint = "Q"', "chain.joint.type", "'Q'"),
    ('joint = "R"', "joint = 3", "chain.joint", "3"),
    ("link_mass = 2.0", "link_mass = nan", "chain.link_mass", "nan"),
    ("link_mass = 2.0", "link_mass = inf", "chain.link_mass", "inf"),
    ("link_mass = 2.0", 'link_mass = "heavy"', "chain.link_mass", "'heavy'"),
    ("radius = 0.02", "radius = -0.02", "chain.radius", "-0.02"),
    ('inertia = "cylinder"', 'inertia = "sphere"', "chain.inertia", "'sphere'"),
    ('inertia = "cylinder"', "inertia = [1.0, -2.0, 1.0]", "chain.inertia", "-2.0"),
    ("q = 0.0", "q = [0.0, 0.0]", "initial.q", "[0.0, 0.0]"),
    ("v = 0.0", "v = [0.0, 0.0, 0.0, 0.0]", "initial.v", "[0.0, 0.0, 0.0, 0.0]"),
    ("q = 0.0", "q = [0.0, nan, 0.0]", "initial.q", "nan"),
    ("v = 0.0", "v = inf", "initial.v", "inf"),
    ("v = 0.0", "v = { fill = 0.0, set = [[7, 1.0]] }", "initial.v.set[0][0]", "7"),
    ("t_end = 1.0", "t_end = -1.0", "simulation.t_end", "-1.0"),
    ("links = 3", "links = 1000000000", "chain.links", "1000000000"),
    ("links = 3", "links = 2.5", "chain.links", "2.5"),
    ("links = 3", "links = 0", "chain.links", "0"),
    ('paper = { tables = ["study_chains"] }', 'paper = { tables = ["table99"] }',
     "case.paper.tables", "'table99'"),
    ("link_length = 1.0", "link_lenght = 1.0", "chain.link_lenght", "1.0"),
])
def test_bad_values_are_named(tmp_path, old, new, field, value):
    assert old in GOOD
    expect(tmp_path, GOOD.replace(old, new), field, value)


@pytest.mark.parametrize("missing,field", [
    ("link_mass = 2.0\n", "chain.link_mass"),
    ('joint = "R"\n', "chain.joint"),
    ("t_end = 1.0\n", "simulation.t_end"),
    ('name = "T"\n', "case.name"),
    ("links = 3\n", "chain.links"),
])
def test_missing_fields_are_named(tmp_path, missing, field):
    path = write(tmp_path, GOOD.replace(missing, ""))
    with pytest.raises(CaseError) as err:
        load_case(path)
    assert field in str(err.value) and str(path) in str(err.value)


def test_toml_syntax_error_names_the_file(tmp_path):
    msg = expect(tmp_path, GOOD.replace("links = 3", "links = = 3"), "<toml syntax>", "line")
    assert "line 7" in msg


def test_missing_case_names_the_known_ones():
    with pytest.raises(FileNotFoundError, match="RE-U125-L1"):
        load_case("RE-U126-L1")


def test_catenary_span_longer_than_the_chain(tmp_path):
    text = GOOD.replace("q = 0.0", 'shape = "catenary"\ndX = 5.0')
    expect(tmp_path, text, "initial.dX", "5.0")


def test_chain_api_errors():
    link = Link(1.0, 1.0, (0.5, 0, 0), ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
    with pytest.raises(CaseError, match=r"links\[0\].mass = -1.0"):
        Chain.build([Link(1.0, -1.0, link.com, link.inertia)], ["R"])
    with pytest.raises(CaseError, match=r"joints\[1\].type = 'X'"):
        Chain.build([link, link], [Joint("R"), Joint("X")])
    with pytest.raises(CaseError, match=r"joints\[0\].axis"):
        Chain.build([link], [Joint("U", "x")])
    with pytest.raises(CaseError, match="one joint per link"):
        Chain.build([link, link], ["R"])


@pytest.mark.parametrize("func", [forward_dynamics, inverse_dynamics, energy, tip])
def test_state_errors_name_the_argument(func):
    chain = Chain.uniform(3, "U", mass=1.0, radius=0.05)
    n = chain.n_dof
    good = [np.zeros(n)] * (3 if func is inverse_dynamics else 2)
    bad = list(good)
    bad[0] = np.zeros(n + 1)
    with pytest.raises(StateError, match=r"q has shape \(7,\).*must have shape \(6,\)"):
        func(chain, *bad)
    bad = list(good)
    bad[1] = np.zeros(n)
    bad[1][4] = math.nan
    with pytest.raises(StateError, match=r"v\[4\] = nan"):
        func(chain, *bad)
    bad = list(good)
    bad[0] = np.zeros(n)
    bad[0][2] = math.inf
    with pytest.raises(StateError, match=r"q\[2\] = inf"):
        func(chain, *bad)
    with pytest.raises(StateError, match="q = 'abc'"):
        func(chain, "abc", *good[1:])


def test_forward_dynamics_names_bad_tau_and_method():
    chain = Chain.uniform(3, "U", mass=1.0, radius=0.05)
    z = np.zeros(6)
    tau = z.copy()
    tau[5] = -math.inf
    with pytest.raises(StateError, match=r"tau\[5\] = -inf"):
        forward_dynamics(chain, z, z, tau)
    with pytest.raises(ValueError, match="method = 'lu'"):
        forward_dynamics(chain, z, z, method="lu")
    with pytest.raises(StateError, match=r"q has shape \(6, 1\)"):
        mass_matrix(chain, z[:, None])


# a U chain (spatial entry point) and a planar R chain (planar entry point), both 6 DOF
ENTRY_CHAINS = {"spatial": lambda: Chain.uniform(3, "U", mass=1.0, radius=0.05),
                "planar": lambda: Chain.uniform(6, "R", mass=1.0, radius=0.05)}


@pytest.mark.parametrize("kind", ENTRY_CHAINS)
@pytest.mark.parametrize("out", [np.empty(5), np.empty(7), np.empty(6, dtype=np.float32),
                                 np.empty(12)[::2], np.empty((6, 1)), [0.0] * 6],
                         ids=["short", "long", "float32", "strided", "2-d", "list"])
def test_forward_dynamics_refuses_an_out_it_cannot_write(out, kind):
    """The kernels write qdd without bounds checks: an ``out`` too short was written past its end
    (heap corruption) before it was checked."""
    chain = ENTRY_CHAINS[kind]()
    assert chain.is_planar == (kind == "planar")
    z = np.zeros(6)
    before = np.array(out, dtype=float, copy=True)
    with pytest.raises(StateError, match=r"out \(.*\) must be a writeable, aligned, contiguous "
                                         r"float64 array of shape \(6,\)"):
        forward_dynamics(chain, z, z, out=out)
    assert np.array_equal(np.array(out, dtype=float), before, equal_nan=True), "written into"


@pytest.mark.parametrize("kind", ENTRY_CHAINS)
def test_forward_dynamics_checks_sizes_before_the_entry_point_writes(kind):
    """Plain float64 vectors go to the compiled entry point unchecked by Python; it checks their
    lengths before anything is written (the kernels index without bounds checks)."""
    chain = ENTRY_CHAINS[kind]()
    z, out = np.zeros(6), np.full(6, 7.0)
    for args, name in (((np.zeros(5), z), "q"), ((z, np.zeros(7)), "v"),
                       ((z, z, np.zeros(5)), "tau")):
        with pytest.raises(StateError, match=rf"{name} has shape"):
            forward_dynamics(chain, *args, out=out)
        assert (out == 7.0).all()
    with pytest.raises(StateError, match=r"out \(shape \(5,\)"):
        forward_dynamics(chain, z, z, out=np.zeros(5))


@pytest.mark.parametrize("kind", ENTRY_CHAINS)
def test_forward_dynamics_refuses_a_read_only_out(kind):
    chain = ENTRY_CHAINS[kind]()
    z = np.zeros(6)
    out = np.empty(6)
    out.flags.writeable = False
    with pytest.raises(StateError, match="writeable False"):
        forward_dynamics(chain, z, z, out=out)
    good = np.empty(6)
    assert forward_dynamics(chain, z, z, out=good) is good


# --------------------------------------------------------------------------- named, not deep
@pytest.mark.parametrize("call, error, fragment", [
    (lambda: Workspace(None), FieldError, "Workspace: model = 'NoneType': must be a redysim."),
    (lambda: Chain.uniform(2.5), CaseError, "n_links = 2.5: must be a whole number"),
    (lambda: Chain.uniform(0), CaseError, "n_links = 0: must be a whole number"),
    (lambda: forward_dynamics(Chain.uniform(2, mass=1.0), [0, 0], [0, 0], ws=object()),
     FieldError, "ws = 'object': must be a redysim.Workspace"),
    (lambda: forward_dynamics(Chain.uniform(2, mass=1.0), [0, 0], [0, 0],
                              ws=Workspace(Chain.uniform(2, mass=1.0))),
     FieldError, "was made for another"),
])
def test_wrong_arguments_get_named_errors(call, error, fragment):
    """These gave an AttributeError from deep inside (Workspace(None)) or a confusing message
    (Chain.uniform(2.5) blamed mass/linear_density)."""
    with pytest.raises(error, match=fragment):
        call()


@pytest.mark.parametrize("method", ["ge-n", "rge-n"])
@pytest.mark.parametrize("gim, fragment", [
    ([[0.0, 0.0], [0.0, 0.0]], "gim is singular for .*pivot of column"),
    ([[1.0, 2.0], [2.0, 4.0]], "gim is singular for .*pivot of column"),
    ([[1.0, np.nan], [0.0, 1.0]], r"gim\[0, 1\] = nan: not finite"),
    ([[1.0, 0.0], [0.0, np.inf]], r"gim\[1, 1\] = inf: not finite"),
])
def test_eliminate_refuses_a_singular_or_non_finite_matrix(gim, fragment, method):
    """It returned NaN qdd."""
    with pytest.raises(StateError, match=fragment):
        eliminate(np.array(gim), np.ones(2), method)
    with pytest.raises(StateError, match=r"rhs\[1\] = nan"):
        eliminate(np.eye(2), [1.0, np.nan], method)


@pytest.mark.parametrize("method, planar", [("rge-a", None), ("rge-a", False), ("ge-n", None),
                                            ("rge-n", None)])
def test_a_singular_chain_is_named_not_called_overflow(method, planar):
    """A link with no inertia about its joint (a point mass on the joint axis) at the tip makes
    the GIM singular: qdd names the DOF, where it said 'overflow?'."""
    point = Link(1.0, 1.0, (0.0, 0.0, 0.0), ((0, 0, 0), (0, 0, 0), (0, 0, 0)))
    rod = Link(1.0, 1.0, (0.5, 0.0, 0.0), ((0.01, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
    chain = Chain.build([rod, rod, point], ["R", "R", "R"])
    named = r"singular at DOF 2 \(joint 'joint3', axis 0 of its R joint\)"
    with pytest.raises(StateError, match=named if method != "ge-n" else r"singular at DOF \d"):
        forward_dynamics(chain, [0.1, 0.2, 0.3], [0, 0, 0], method=method, planar=planar)


def test_a_link_length_that_underflows_is_named(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(GOOD.replace("link_length = 1.0", "link_length = 5e-324")
                    .replace("link_mass = 2.0", "density = 7025.0"))
    case = load_case(path)  # a length is a length; what it does to the dynamics is named there
    with pytest.raises(StateError, match="singular at DOF"):
        forward_dynamics(case.chain, [0.1, 0.1, 0.1], case.v0)


def test_every_field_naming_error_has_one_base():
    """CaseError, SettingsError, SweepError and GatesError (which was not a RedysimError) are all
    FieldErrors: one way to catch a bad field, with its source, field and value."""
    from redysim.errors import RedysimError, SettingsError
    from redysim.harness.gates import GatesError
    from redysim.harness.sweep import SweepError

    for cls in (CaseError, SettingsError, SweepError, GatesError):
        assert issubclass(cls, FieldError) and issubclass(cls, RedysimError), cls
        err = cls("file.toml", "a.b", 3, "must be 4")
        assert str(err) == "file.toml: a.b = 3: must be 4"
        assert (err.source, err.field, err.value, err.problem) == ("file.toml", "a.b", 3,
                                                                   "must be 4")
