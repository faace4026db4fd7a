"""`hamnet policy` start-up: the parameter table, and clear errors before any network use."""

from __future__ import annotations

import pytest

from hamnet.policy.cli import main
from hamnet.policy.params import counts
from hamnet.policy.registry import ARCHITECTURES


def test_print_params_lists_every_architecture_next_to_the_paper(capsys) -> None:
    assert main(["--print-params"]) == 0
    out = capsys.readouterr().out
    assert all(f"\n{name} " in out for name in ARCHITECTURES) and "1.76 M" in out


def test_the_mlp_baseline_has_as_many_parameters_as_hamnet() -> None:
    """The paper sizes its MLP to match HAMnet's trainable parameters; a change to either
    network that breaks the match (and the fairness of the speed and success comparisons)
    fails here."""
    hamnet, mlp = counts("hamnet")[0], counts("mlp")[0]
    assert abs(mlp / hamnet - 1.0) < 0.01, (hamnet, mlp)


def test_missing_or_bad_checkpoint_stops_at_start(tmp_path, capfd) -> None:
    assert main(["--checkpoint", str(tmp_path / "absent.safetensors")]) == 2
    (tmp_path / "bad.safetensors").write_bytes(b"not weights")
    assert main(["--weights", str(tmp_path / "bad.safetensors")]) == 2
    with pytest.raises(SystemExit) as exited:  # refused while parsing: `hamnet up --check` too
        main([])
    assert exited.value.code == 2
    logged = capfd.readouterr()
    assert "nor a shipped policy of that name; shipped:" in logged.err  # names what exists
    assert "not safetensors" in logged.err
    assert "needs --checkpoint" in logged.out + logged.err


def test_unknown_random_init_architecture_is_refused(capfd) -> None:
    """`raises(SystemExit)` alone passed on any parse error, a renamed flag included: the
    refusal must be the usage error (2) that names the unknown architecture and lists the
    known ones, and a known architecture must get through the same parse."""
    with pytest.raises(SystemExit) as exited:
        main(["--random-init", "resnet"])
    assert exited.value.code == 2
    err = capfd.readouterr().err
    assert "unknown architecture 'resnet'" in err
    assert all(name in err for name in ARCHITECTURES)
    assert main(["--random-init", "mlp", "--print-params"]) == 0
