"""Small builders of AAS submodel elements (Eclipse BaSyx), each with its semantic id from a
template (bwr_twin.export.aas_templates), and the units of measure as IEC 61360 concept
descriptions whose unit id names the IEC Common Data Dictionary's unit (IEC 62720) where the
docs list one (docs/aas.md)."""

from __future__ import annotations

import re

from basyx.aas import model

from bwr_twin.export.aas_templates import Template

# Unit symbol -> its IEC 62720 (IEC CDD) unit IRDI, for the units the docs list one for; the
# others are given by symbol only (docs/aas.md says which).
UNIT_IRDI = {"m": "0112/2///62720#UAA726", "N": "0112/2///62720#UAA235", "W": "0112/2///62720#UAA306",
             "V": "0112/2///62720#UAA296", "A": "0112/2///62720#UAA101", "kg": "0112/2///62720#UAA594"}


def reference(value: str) -> model.ExternalReference:
    """A global reference to `value`, as a semantic id is written."""
    return model.ExternalReference((model.Key(model.KeyTypes.GLOBAL_REFERENCE, value),))


def id_short(text: str) -> str:
    """An idShort made of `text`: letters, digits and underscores, starting with a letter."""
    cleaned = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return cleaned if cleaned[:1].isalpha() else f"X{cleaned}"


def prop(template: Template, name: str, value, *, as_name: str | None = None, semantic: str | None = None,
         value_type=model.datatypes.String) -> model.Property:
    """A Property `as_name` (default: `name`) with the template's semantic id of `name`."""
    return model.Property(as_name or name, value_type, value=value,
                          semantic_id=reference(semantic or template.id(name)))


def text(template: Template, name: str, value: str, *, as_name: str | None = None) -> model.MultiLanguageProperty:
    """A MultiLanguageProperty in English."""
    return model.MultiLanguageProperty(as_name or name, value=model.MultiLanguageTextType({"en": value}),
                                       semantic_id=reference(template.id(name)))


def collection(template: Template, name: str, *elements, as_name: str | None = None,
               semantic: str | None = None) -> model.SubmodelElementCollection:
    return model.SubmodelElementCollection(as_name or name, value=[e for e in elements if e is not None],
                                           semantic_id=reference(semantic or template.id(name)))


def file(template: Template, name: str, path: str, content_type: str, *, as_name: str | None = None) -> model.File:
    """A File element pointing at `path` inside the package."""
    return model.File(as_name or name, content_type=content_type, value=path,
                      semantic_id=reference(template.id(name)))


class Measures:
    """The concept descriptions of measured properties: one per quantity, with its unit and,
    where the docs list one, the unit's IEC CDD IRDI; `measure` returns a Property that points
    at its concept."""

    def __init__(self, namespace: str):
        self.namespace = namespace
        self.concepts: dict[str, model.ConceptDescription] = {}

    def measure(self, name: str, value: float, unit: str, definition: str) -> model.Property:
        concept_id = f"{self.namespace}:{name}"
        if concept_id not in self.concepts:
            unit_id = reference(UNIT_IRDI[unit]) if unit in UNIT_IRDI else None
            content = model.DataSpecificationIEC61360(
                preferred_name=model.PreferredNameTypeIEC61360({"en": name}), unit=unit, unit_id=unit_id,
                data_type=model.DataTypeIEC61360.REAL_MEASURE,
                definition=model.DefinitionTypeIEC61360({"en": f"{definition} [{unit}]"}))
            spec = model.EmbeddedDataSpecification(
                reference("https://admin-shell.io/DataSpecificationTemplates/DataSpecificationIEC61360/3/0"),
                content)
            self.concepts[concept_id] = model.ConceptDescription(concept_id, id_short=id_short(name),
                                                                 embedded_data_specifications=[spec])
        return model.Property(id_short(name), model.datatypes.Double, value=float(value),
                              semantic_id=model.ModelReference((model.Key(model.KeyTypes.CONCEPT_DESCRIPTION,
                                                                          concept_id),), model.ConceptDescription),
                              description=model.MultiLanguageTextType({"en": f"{definition}, {unit}"}))
