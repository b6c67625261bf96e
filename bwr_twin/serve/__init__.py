"""The twin as an OPC UA server: one run of a scene is the machine, a PLC (the client) computes
the drive forces. `python -m bwr_twin.serve SCENE`; the contract is docs/opcua.md. The machine
is bwr_twin.sim.twin (one run, advanced a control period at a time), each analog variable's
EURange bwr_twin.sim.ranges (from the MJCF or a documented rule); the FMU serves the same twin.

    address_space.py  Objects/Reclaimer/...: variables, units, methods, publishing
    machinery.py      OPC 40001-1: Objects/Machines, Identification, MachineryItemState, operation mode
    alarms.py         limit switches and watchdog trips as alarm events on Objects/Reclaimer; ConditionRefresh
    sensing.py        the scanners' latest profiles and the faults' states, where the run has them
    nodes.py          typed nodes with the twin's node ids, which asyncua's shortcuts do not make
    nodeset.py        --nodeset: the address space as a UA NodeSet2 file
    clock.py          lockstep and real-time modes, setpoints, watchdog, overruns, the path's last period
    methods.py        method calls checked as Part 4 says: the object, the arguments' number and types
    writes.py         a Write answered and applied node by node
    security.py       users file, password hashes, who may write (and reads so); policies per endpoint
    user_certificates.py  --user-certificates: users who log in with an X.509 certificate
    logins.py         password checks in a worker thread, before asyncua activates a session
    certificates.py   the certificate and key checked at start: a pair, naming the application URI
    announce.py       what the server prints it exposes
    results.py        --out: a completed path's run directory
    server.py         the asyncua server around them, start to clean stop
    cli.py            the command line
    passwd.py         a users-file line: python -m bwr_twin.serve.passwd NAME
"""

from bwr_twin.errors import BwrError

# Kept here, light, so that the command line checks its arguments before importing asyncua and MuJoCo.
LOCKSTEP, REALTIME = "lockstep", "realtime"
DEFAULT_WATCHDOG_PERIODS = 10  # control periods without a DriveSetpoint write before the drives stop


class ServeError(BwrError):
    """An endpoint or option the server cannot serve."""
