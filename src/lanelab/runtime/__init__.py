"""Machinery for running a model, about no paper: the GPU work of a call recorded once as a CUDA
graph and replayed (``cuda_graph``), the ATen operators a call dispatches (``operator_log``), and
top-k picks that agree across backends, recorded and replayed (``ranking``). The models import it;
it imports no model. The explicit streaming state that exported graphs carry is
:mod:`lanelab.deploy.explicit_state`'s (it imports the detectors)."""
