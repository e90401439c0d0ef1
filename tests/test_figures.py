import os
import stat

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from helpers import figures  # noqa: E402


def test_save_writes_png_and_pdf(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    figures.use_style()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    png, pdf = figures.save(fig, "unit_test_fig")
    plt.close(fig)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pdf.read_bytes()[:5] == b"%PDF-"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["unit_test_fig.pdf", "unit_test_fig.png"]


def test_save_pdf_is_deterministic(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    _, pdf = figures.save(fig, "a")
    first = pdf.read_bytes()
    _, pdf = figures.save(fig, "a")
    plt.close(fig)
    assert pdf.read_bytes() == first


@pytest.mark.parametrize("name", ["", "../x", "a/b", "x.png", None])
def test_save_rejects_bad_names(name, tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    fig, _ = plt.subplots()
    with pytest.raises(ValueError, match="name"):
        figures.save(fig, name)
    plt.close(fig)


def test_save_rejects_non_figure():
    with pytest.raises(ValueError, match="fig"):
        figures.save("not a figure", "x")


# ---------------------------------------------------------------------------------------------- robustness (issue 14)
def _figure():
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    return fig


@pytest.mark.parametrize("name", ["name\n", "name\r", "a" * (figures.MAX_NAME_LENGTH + 1), "a" * 300, ".hidden",
                                  "x.pdf", "café", "a b", 5, b"bytes"])
def test_save_rejects_more_bad_names(name, tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    fig = _figure()
    with pytest.raises(ValueError, match="name must be a plain file stem"):
        figures.save(fig, name)
    plt.close(fig)
    assert list(tmp_path.iterdir()) == []


def test_save_accepts_the_longest_name(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    fig = _figure()
    png, pdf = figures.save(fig, "a" * figures.MAX_NAME_LENGTH)
    plt.close(fig)
    assert png.name == "a" * figures.MAX_NAME_LENGTH + ".png" and pdf.exists()


@pytest.mark.parametrize("where", ["file", "under_file"])
def test_figures_dir_that_is_not_a_directory(where, tmp_path, monkeypatch):
    afile = tmp_path / "file"
    afile.write_text("x")
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(afile if where == "file" else afile / "sub"))
    fig = _figure()
    with pytest.raises(ValueError, match="WORKBOOK_FIGURES_DIR"):
        figures.save(fig, "x")
    plt.close(fig)


@pytest.mark.parametrize("failing", ["png", "pdf"])
def test_a_failed_save_keeps_the_old_pair_and_leaves_no_temporaries(failing, tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    fig = _figure()
    figures.save(fig, "pair")
    old = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    fig.axes[0].plot([0, 1], [0, 1], color="r")       # a changed figure
    save = fig.savefig

    def broken(fname, format=None, **kwargs):
        if format == failing:
            raise RuntimeError(f"{format} backend failed")
        return save(fname, format=format, **kwargs)
    monkeypatch.setattr(fig, "savefig", broken)
    with pytest.raises(RuntimeError, match="backend failed"):
        figures.save(fig, "pair")
    plt.close(fig)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == old


def test_saved_files_have_the_usual_mode(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    umask = os.umask(0o022)
    try:
        fig = _figure()
        png, pdf = figures.save(fig, "mode")
        plt.close(fig)
    finally:
        os.umask(umask)
    assert stat.S_IMODE(png.stat().st_mode) == stat.S_IMODE(pdf.stat().st_mode) == 0o644
