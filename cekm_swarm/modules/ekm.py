"""What the cooperative-EKM nodes share: the controller of the run's model, built once per
process for each set of field parameters (:meth:`cekm_swarm.node.Context.shared`)."""

from __future__ import annotations

from cekm_swarm.controller.cooperative import CooperativeEKM
from cekm_swarm.errors import CekmError
from cekm_swarm.models.networks import IndirectEKM
from cekm_swarm.models.params import FieldParams
from cekm_swarm.node import Context, NodeError


def indirect_model(ctx: Context) -> IndirectEKM:
    """The run's model, which must be an indirect-mapping EKM (Eq. 1)."""
    try:
        model: IndirectEKM = ctx.model()  # checked to be one below
    except CekmError as exc:  # names the model file and what is wrong with it
        raise NodeError(str(exc)) from None
    if not str(getattr(model, "kind", "")).startswith("indirect"):
        where = ctx.model_source if isinstance(ctx.model_source, str) else "the model"
        raise NodeError(f"{where}: the controller needs an indirect-mapping EKM, not {getattr(model, 'kind', model)!r}")
    return model


def cooperative_ekm(ctx: Context, fields: FieldParams | None = None, allow_reverse: bool = False,
                    reverse_min_d: float = 0.02) -> CooperativeEKM:
    """The run's cooperative EKM with ``fields`` (Eqs. 6, 8), shared by the nodes of a process."""
    model = indirect_model(ctx)
    fields = fields or FieldParams()
    key = ("cooperative-ekm", id(model), fields, allow_reverse, reverse_min_d, ctx.backend)

    def make() -> CooperativeEKM:
        return CooperativeEKM(model, fields, allow_reverse, reverse_min_d, backend=ctx.backend)

    ekm: CooperativeEKM = ctx.shared(key, make)
    if ekm.model is not model:  # a model object freed and its id reused: build afresh
        ekm = make()
    return ekm
