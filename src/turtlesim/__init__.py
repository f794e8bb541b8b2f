# The generated turtlesim.msg / turtlesim.srv live in the catkin devel (or install) space, this source in src/:
# extend the package path so that both halves are found whichever comes first on sys.path.
import pkgutil

__path__ = pkgutil.extend_path(__path__, __name__)
