"""The twin's models leave the twin: `python -m bwr_twin.export plc|fmu|aas SCENE --out ...`.

    plc.py, blocks.py, structured_text.py, plcopen.py   the controller as IEC 61131-3 code
    fmu.py, fmu_slave.py                                one run as an FMI co-simulation FMU
    aas.py              the machine as an Asset Administration Shell package, and its check
    aas_machine.py      its Digital Nameplate and Technical Data, from the compiled model
    aas_models.py       its simulation models, control software and OPC UA endpoint
    aas_fmu.py          what an FMU says of itself (modelDescription.xml, binaries/)
    aas_templates.py    the IDTA templates' semantic ids and required elements, and the check
    aas_elements.py     small builders of submodel elements, and units as concept descriptions
"""
