"""A subject's intent model as a recording keeps it: written and read back to the same filter tuning; a bad record
is a clear error, never a silent default."""

from __future__ import annotations

import pytest

from gaitscope.estimators.intent import COHORT, ISCI
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.personalization.intent_model import config_of, default_model, from_metadata, to_metadata


def test_what_a_recording_keeps_builds_the_same_filter() -> None:
    fitted = default_model(1, "uninjured", "root").model_copy(update={"kappa": (0.3, 0.25, 0.41)})
    for model in (fitted, default_model(1, "isci", "root")):
        config = config_of(model)
        assert from_metadata(to_metadata(config, model.variant), "t.mcap") == config
    assert config_of(None) == COHORT and config_of(default_model(2, "isci", "x")) == ISCI
    assert from_metadata(None) is None and from_metadata("") is None  # recorded before #26: the cohort's


@pytest.mark.parametrize(
    "text",
    [
        "not json",
        '{"variant": "isci"}',
        '{"variant": "other", "kappa": [0.1, 0.2, 0.3], "alpha": null}',
        '{"variant": "uninjured", "kappa": [0.1, 0.2], "alpha": null}',
        '{"variant": "uninjured", "kappa": [0.1, 0.2, NaN], "alpha": null}',
        '{"variant": "isci", "kappa": [0.1, 0.2, 0.3], "alpha": [1.0]}',
    ],
)
def test_a_bad_record_is_an_error_naming_the_file(text: str) -> None:
    with pytest.raises(DataFormatError, match=r"intent model") as e:
        from_metadata(text, "trial.mcap")
    assert "trial.mcap" in str(e.value) or e.value.file == "trial.mcap"


def test_a_request_beyond_the_schema_is_refused() -> None:
    with pytest.raises(ValueError):
        schema.IntentModelRequest.model_validate({"variant": "isci", "kappa": [1, 2, 3]})
    with pytest.raises(ValueError):
        schema.IntentModelRequest.model_validate({"trial_id": -1})
