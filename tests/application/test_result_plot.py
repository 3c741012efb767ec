"""Response.plot and Response.to_dataframe: units from the DOF kind (a shaft's rotations in rad,
a beam's w and psi apart), DOFs by name or 0-based index, the DataFrame equal to the CSV, and
the app's scene plot labelled the same way."""
import sys

import numpy as np
import pytest

import dtdyn as dd

pytest.importorskip("matplotlib")
from matplotlib.figure import Figure  # noqa: E402

SHAFT = dd.Shaft([1.0, 2.0, 1.5], [1e4, 2e4, 2e4], [1.0, 1.0, 1.0])


def labels(ax) -> list[str]:
    return ax.get_legend_handles_labels()[1]


def test_shaft_plot_labels_radians():
    r = dd.shaft_response(SHAFT, np.ones(101), 1e-3, force_dofs=["main.2"])
    fig = r.plot(fig=Figure())
    axes = fig.axes
    assert [ax.get_ylabel() for ax in axes] == ["x [rad]", "v [rad/s]", "a [rad/s^2]"]
    assert [ax.get_title(loc="left") for ax in axes] == [
        "rotation", "angular velocity", "angular acceleration"]
    assert all(labels(ax) == ["main.0", "main.1", "main.2"] for ax in axes)
    assert axes[-1].get_xlabel() == "t [s]"
    line = axes[1].get_lines()[2]  # the data drawn is the response's
    np.testing.assert_array_equal(line.get_xdata(), r.t)
    np.testing.assert_array_equal(line.get_ydata(), r.v[:, 2])


def test_nonlinear_shaft_element_moments_in_newton_metres():
    r = dd.nonlinear_shaft_response(SHAFT, np.full(51, 50.0), 1e-3, force_dofs=["main.2"],
                                    elements=[dd.Cubic(SHAFT.dof("main.1"), k3=1e9)],
                                    quantities=("x", "g"), backend="numpy")
    fig = r.plot(fig=Figure())
    assert [ax.get_ylabel() for ax in fig.axes] == ["x [rad]", "g [N m]"]
    assert labels(fig.axes[1]) == ["element 0"]


def test_beam_plot_puts_metres_and_radians_apart_and_picks_outputs():
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=10)
    r = dd.beam_response(beam, np.ones(51), 1e-4, force_dofs=["w10"],
                         outputs=["w10", "psi10", "w5"], quantities=("x",), backend="numpy")
    fig = r.plot(fig=Figure())
    assert [ax.get_ylabel() for ax in fig.axes] == ["x [m]", "x [rad]"]
    assert [labels(ax) for ax in fig.axes] == [["w10", "w5"], ["psi10"]]
    fig = r.plot(outputs=["psi10"], fig=Figure())
    assert [ax.get_ylabel() for ax in fig.axes] == ["x [rad]"]
    np.testing.assert_array_equal(fig.axes[0].get_lines()[0].get_ydata(), r.x[:, 1])


def test_chain_plot_uses_zero_based_indices_and_given_axes():
    r = dd.chain_response([1.0, 1.0, 1.0], [4.0, 4.0, 4.0], [0.1, 0.1, 0.1], np.ones(21), 0.1,
                          force_dofs=[2], outputs=[2, 0], quantities=("x", "a"))
    fig = Figure()
    axes = fig.subplots(1, 2)
    assert r.plot(ax=axes, outputs=[0]) is fig
    assert [ax.get_ylabel() for ax in axes] == ["x [m]", "a [m/s^2]"]
    assert labels(axes[0]) == ["DOF 0"] and labels(axes[1]) == ["DOF 0"]
    np.testing.assert_array_equal(axes[0].get_lines()[0].get_ydata(), r.x[:, 1])
    with pytest.raises(ValueError, match="ax holds 1 axes for 2 subplots"):
        r.plot(ax=Figure().subplots())
    with pytest.raises(ValueError, match=r"quantities holds 'v', which the response did not "
                                         r"store \(stored: x, a\)"):
        r.plot(quantities=["v"], fig=Figure())
    with pytest.raises(ValueError, match="quantities holds 'y': not a Response quantity"):
        r.plot(quantities="y", fig=Figure())
    with pytest.raises(ValueError, match=r"outputs holds DOF 1, which is not among the stored "
                                         r"outputs \[2, 0\]"):
        r.plot(outputs=[1], fig=Figure())
    with pytest.raises(ValueError, match="outputs holds 'roof', which is not a stored DOF name"):
        r.plot(outputs=["roof"], fig=Figure())


def test_plot_without_a_figure_makes_a_pyplot_one():
    import matplotlib.pyplot as plt

    r = dd.chain_response([1.0], [4.0], [0.1], np.ones(11), 0.1, quantities=("x",))
    fig = r.plot()
    try:
        assert fig.number in plt.get_fignums() and fig.axes[0].get_ylabel() == "x [m]"
    finally:
        plt.close(fig)


def test_many_dofs_are_a_heat_map_with_dof_indices():
    r = dd.chain_response(np.ones(12), np.full(12, 4.0), np.full(12, 0.1), np.ones(21), 0.1,
                          force_dofs=[11], quantities=("x",))
    fig = r.plot(fig=Figure())
    ax = fig.axes[0]
    assert ax.get_ylabel() == "DOF" and not ax.get_lines()
    ticks = [t.get_text() for t in ax.get_yticklabels()]
    assert ticks[0] == "0" and ticks[-1] == "11"
    assert fig.axes[1].get_ylabel() == "x [m]"  # the colour bar


def test_to_dataframe_equals_the_csv(tmp_path):
    pd = pytest.importorskip("pandas")
    r = dd.shaft_response(SHAFT, np.ones(101), 1e-3, force_dofs=["main.2"], quantities=("x", "a"))
    df = r.to_dataframe()
    path = r.save(tmp_path / "s.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert list(df.columns) == header and header[:2] == ["t [s]", "x main.0 [rad]"]
    np.testing.assert_array_equal(df["a main.1 [rad/s^2]"].to_numpy(), r.a[:, 1])
    pd.testing.assert_frame_equal(df, pd.read_csv(path), check_exact=False, rtol=4e-16, atol=0)


def test_missing_pandas_names_the_extra(monkeypatch):
    r = dd.chain_response([1.0], [4.0], [0.1], np.ones(11), 0.1, quantities=("x",))
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r'Response.to_dataframe needs pandas, which is not '
                                          r'installed: pip install "dtdyn\[pandas\]"'):
        r.to_dataframe()


def test_scene_plots_label_rotations_and_zero_based_dofs(tmp_path, monkeypatch):
    """`dtdyn simulate --plot`: a shaft scene's panels in rad and rad/s with the DOF names; the
    default (P3) chain's heat map counts DOFs 0..14 and nothing says "mass"."""
    from dtdyn.app._scene import io

    drawn = []
    real = dd.Response.plot

    def spy(self, *args, **kwargs):
        fig = real(self, *args, **kwargs)
        drawn.append(fig)
        return fig

    monkeypatch.setattr(dd.Response, "plot", spy)
    scene = tmp_path / "shaft.toml"
    scene.write_text('title = "shaft"\n[model]\nkind = "shaft"\ninertia = [1.0, 0.3, 0.9]\n'
                     'stiffness = [1e4, 1.2e4, 9e3]\ndamping = [0.5, 0.8, 0.3]\n'
                     '[[load]]\ndof = "main.2"\nkind = "step"\n[scheme]\nname = "newmark"\n'
                     '[time]\ndt = 0.001\nduration = 0.1\n[output]\nquantities = ["x", "v"]\n')
    s = dd.load_scene(scene)
    r, _ = dd.run_scene(s)
    io.plot_response(tmp_path / "shaft.png", r, s)
    fig = drawn.pop()
    assert [ax.get_ylabel() for ax in fig.axes] == ["x [rad]", "v [rad/s]"]
    assert labels(fig.axes[0]) == ["main.0", "main.1", "main.2"]
    assert (tmp_path / "shaft.png").read_bytes()[:4] == b"\x89PNG"

    p3 = dd.load_scene(None)
    r, _ = dd.run_scene(p3, check=False)
    io.plot_response(tmp_path / "p3.png", r, p3)
    fig = drawn.pop()
    ticks = [t.get_text() for t in fig.axes[0].get_yticklabels()]
    assert ticks[0] == "0" and ticks[-1] == "14" and fig.axes[0].get_ylabel() == "DOF"
    assert "mass" not in fig.get_suptitle()
