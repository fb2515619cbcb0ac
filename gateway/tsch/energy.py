"""Energy of a TSCH node per slot type, from a named radio's measured charges; batteries.

In TSCH the radio is on only in the slots of the node's cells, so a node's charge is a sum over
slots of the charge of what it did in each (the 6TiSCH simulator's model, after Vilajosana et
al., "A realistic energy consumption model for TSCH networks", IEEE Sensors Journal 14(2),
2014)::

    Q = n_txack Q_TxDataRxAck + n_txnone Q_TxDataRxAckNone + n_rxack Q_RxDataTxAck
        + n_idle Q_IdleListen + n_sleep Q_Sleep

* ``TxDataRxAck``: a transmission in a TX cell whose acknowledgement came back;
  ``TxDataRxAckNone``: a transmission whose acknowledgement did not come (lost frame or
  collision): the node listened for it all the same;
* ``RxDataTxAck``: a frame received in an RX cell and acknowledged; ``IdleListen``: an RX cell
  in which no frame was decoded (the radio listened for the guard time, nothing came);
* ``Sleep``: every other slot (a TX cell with an empty queue is a sleeping slot too).

Radios (:data:`RADIOS`, charges in microcoulombs per 10 ms slot):

* ``openmote_cc2538``: the 6TiSCH simulator's charges for the OpenMote-CC2538
  (``SimEngine/Mote/MoteDefines.py``: Idle 6.4, TxDataRxAck 54.5, TxData 49.5,
  TxDataRxAckNone 54.5, RxDataTxAck 32.6 uC), with sleep at the CC2538's power mode 2 current,
  1.3 uA (TI, *CC2538 datasheet*, SWRS096, table "Current consumption": PM2 1.3 uA), i.e.
  0.013 uC per 10 ms slot;
* ``vilajosana2014``: the charges measured by Vilajosana et al. (2014) and used by the earlier
  6TiSCH simulator (``Mote.py``: Idle 24.60, TxDataRxAck 64.82, TxData 49.37, RxDataTxAck
  76.90 uC), the same sleep current.

A slot of another duration scales the idle and sleep charges with it (they are listening and
sleeping times); the frame charges stay (a frame's air time does not change).
"""

from __future__ import annotations

from collections.abc import Mapping

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["SLOT_KINDS", "RadioCharges", "RADIOS", "charge_uC"]

SLOT_KINDS = ("tx_ack", "tx_noack", "rx_ack", "idle", "sleep")
"""The slot types a node is charged for: TxDataRxAck, TxDataRxAckNone, RxDataTxAck,
IdleListen, Sleep."""

_REFERENCE_SLOT_S = 0.010  # the slot duration the measured charges belong to


class RadioCharges(BaseModel):
    """Charge per slot type of one radio, for a 10 ms slot (microcoulombs)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str
    tx_ack_uC: float = Field(ge=0, description="TxDataRxAck: frame sent, acknowledged")
    tx_noack_uC: float = Field(ge=0, description="TxDataRxAckNone: frame sent, no ACK")
    rx_ack_uC: float = Field(ge=0, description="RxDataTxAck: frame received and acknowledged")
    idle_uC: float = Field(ge=0, description="IdleListen: RX cell, nothing received")
    sleep_uA: float = Field(ge=0, description="current asleep, microamperes")
    source: str = ""

    def charge_uC(self, kind: str, slot_s: float) -> float:
        """Charge of one slot of ``kind`` (:data:`SLOT_KINDS`) lasting ``slot_s`` seconds."""
        scale = slot_s / _REFERENCE_SLOT_S
        return {
            "tx_ack": self.tx_ack_uC,
            "tx_noack": self.tx_noack_uC,
            "rx_ack": self.rx_ack_uC,
            "idle": self.idle_uC * scale,
            "sleep": self.sleep_uA * slot_s,
        }[kind]


RADIOS: dict[str, RadioCharges] = {
    "openmote_cc2538": RadioCharges(
        name="openmote_cc2538",
        tx_ack_uC=54.5,
        tx_noack_uC=54.5,
        rx_ack_uC=32.6,
        idle_uC=6.4,
        sleep_uA=1.3,
        source="6TiSCH simulator SimEngine/Mote/MoteDefines.py; TI CC2538 datasheet PM2",
    ),
    "vilajosana2014": RadioCharges(
        name="vilajosana2014",
        tx_ack_uC=64.82,
        tx_noack_uC=49.37,
        rx_ack_uC=76.90,
        idle_uC=24.60,
        sleep_uA=1.3,
        source="Vilajosana et al., IEEE Sensors J. 14(2), 2014 (6TiSCH simulator Mote.py)",
    ),
}
"""The radios a scenario may name (``tsch.radio``)."""


def charge_uC(radio: RadioCharges, counts: Mapping[str, int], slot_s: float) -> float:
    """Charge of ``counts`` slots of each kind (:data:`SLOT_KINDS`) with ``radio``."""
    return sum(n * radio.charge_uC(kind, slot_s) for kind, n in sorted(counts.items()))
