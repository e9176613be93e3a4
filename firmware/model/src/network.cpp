#include "zerog/model/network.hpp"

#include <cstring>

namespace zerog::model {

const char* activation_name(Activation a) {
  switch (a) {
    case Activation::sigmoid:
      return "sigmoid";
    case Activation::leaky_relu:
      return "leaky_relu";
    case Activation::tanh:
      return "tanh";
    case Activation::identity:
      break;
  }
  return "identity";
}

bool activation_from_name(const char* name, Activation& out) {
  for (Activation a :
       {Activation::identity, Activation::sigmoid, Activation::leaky_relu, Activation::tanh}) {
    if (std::strcmp(name, activation_name(a)) == 0) {
      out = a;
      return true;
    }
  }
  return false;
}

}  // namespace zerog::model
