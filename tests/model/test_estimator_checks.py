"""scikit-learn's own estimator API checks on MPPCA (sklearn 1.9 ``parametrize_with_checks``).

Every check is expected to pass. The one that reports "skipped" is ``check_array_api_input``:
sklearn skips it unless the SCIPY_ARRAY_API environment variable is set, and MPPCA does not
declare array-API support (it computes in float64 numpy only). The small settings (q = 1,
two components, few iterations) keep the checks fast. On the 1-feature data of
``check_fit2d_1feature`` fit raises "n_latent = 1 must be smaller than n_features = 1" (or, with the
default n_latent, "n_features = 1, but a mixture of PPCA needs at least 2 features"), an error
that check explicitly accepts. The second estimator keeps the default ``n_latent`` (None: min(10,
n_features - 1)); with the former default of 10 it refused every check's data of 10 features or fewer.
"""

import warnings

from sklearn.exceptions import ConvergenceWarning
from sklearn.utils.estimator_checks import parametrize_with_checks

from silpose.model.mppca import MPPCA


@parametrize_with_checks([
    MPPCA(n_components=2, n_latent=1, n_init=1, max_iter=20, random_state=0),
    MPPCA(n_init=1, max_iter=20, random_state=0),  # the default n_latent on the checks' 2- to 10-feature data
])
def test_sklearn_estimator_checks(estimator, check):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        check(estimator)
